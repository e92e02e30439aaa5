"""Naive surface nets: a closed triangle mesh of the zero level set of a sampled scalar field.

One vertex per grid cell that the surface crosses (the mean of the linear edge crossings), one quad (two
triangles) per crossing grid edge. The field is padded with an outside layer, so the result is closed.
Faces are oriented counter-clockwise seen from outside (outside is ``field >= 0``).
"""

from __future__ import annotations

import numpy as np


def surface_nets(field: np.ndarray, origin: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Mesh of ``field == 0`` for ``field`` (X, Y, Z) sampled at ``origin + spacing * (i, j, k)`` (metres).

    Negative values are inside. Returns vertices (V, 3) float64 and faces (F, 3) int64 (empty when the
    field has no sign change).
    """
    pad_value = max(float(np.nanmax(np.abs(field))), 1.0)
    f = np.pad(np.asarray(field, dtype=np.float64), 1, constant_values=pad_value)
    inside = f < 0
    shape = np.array(f.shape)
    cells = shape - 1
    vsum = np.zeros((int(np.prod(cells)), 3))
    vcount = np.zeros(int(np.prod(cells)))
    crossings = []
    for a in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[a], hi[a] = slice(0, -1), slice(1, None)
        cross = inside[tuple(lo)] != inside[tuple(hi)]
        idx = np.argwhere(cross)  # edge start grid index
        f0, f1 = f[tuple(lo)][cross], f[tuple(hi)][cross]
        t = f0 / (f0 - f1)
        point = idx.astype(np.float64)
        point[:, a] += t
        b, c = (a + 1) % 3, (a + 2) % 3
        cell_ids = []
        for db, dc in ((-1, -1), (0, -1), (0, 0), (-1, 0)):
            cell = idx.copy()
            cell[:, b] += db
            cell[:, c] += dc
            flat = np.ravel_multi_index(cell.T, cells)
            np.add.at(vsum, flat, point)
            np.add.at(vcount, flat, 1.0)
            cell_ids.append(flat)
        quads = np.stack(cell_ids, axis=1)
        flip = ~inside[tuple(lo)][cross]  # inside at the edge end: outward normal is -axis
        quads[flip] = quads[flip][:, ::-1]
        crossings.append(quads)
    quads = np.concatenate(crossings) if crossings else np.zeros((0, 4), np.int64)
    active = np.nonzero(vcount)[0]
    remap = np.full(len(vcount), -1, dtype=np.int64)
    remap[active] = np.arange(len(active))
    verts = vsum[active] / vcount[active, None]
    verts = np.asarray(origin, dtype=np.float64) + (verts - 1.0) * spacing  # undo the padding
    q = remap[quads]
    faces = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    return verts, faces
