"""Implicit surfaces for the synthetic garments: an elliptic frustum, a smooth union, and meshing (marching cubes ->
isotropic remeshing -> one closed, consistently oriented component), cutting and largest components.

Fields are approximate signed distances in metres: negative inside. The smooth union is the log-sum-exp
smooth minimum, which is order independent and never smaller than ``min - k log(n)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError


@dataclass(frozen=True)
class Cone:
    """A vertical elliptic frustum (a skirt): radius r_top at y_top, r_bottom at y_bottom, depth scales z."""

    center: tuple[float, float]
    """(x, z) of the axis."""
    y_top: float
    y_bottom: float
    r_top: float
    r_bottom: float
    depth: float = 1.0


def cone_field(points: np.ndarray, cone: Cone, inflate: float = 0.0) -> np.ndarray:
    """Approximate signed distance to a capped elliptic frustum grown by ``inflate``."""
    x, y, z = points[:, 0] - cone.center[0], points[:, 1], (points[:, 2] - cone.center[1]) / cone.depth
    t = np.clip((cone.y_top - y) / (cone.y_top - cone.y_bottom), 0.0, 1.0)
    radius = cone.r_top + t * (cone.r_bottom - cone.r_top) + inflate
    side = np.hypot(x, z) - radius
    caps = np.maximum(y - cone.y_top - inflate, cone.y_bottom - inflate - y)
    return np.maximum(side, caps)


def smooth_union(fields: list[np.ndarray], k: float) -> np.ndarray:
    """Log-sum-exp smooth minimum of signed fields with blend radius ``k`` metres."""
    stack = np.stack(fields)
    m = stack.min(axis=0)
    return m - k * np.log(np.exp(-(stack - m) / k).sum(axis=0))


def mesh_field(field_fn, lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Marching cubes of the zero level of ``field_fn`` (points (N, 3) -> (N,)) over the box [lo, hi].

    Returns (V, 3) vertices and (F, 3) faces oriented counter-clockwise seen from outside.
    """
    from skimage.measure import marching_cubes

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    values = _sample_narrow_band(field_fn, lo, hi, spacing)
    if values.min() >= 0 or min(values[0].min(), values[-1].min(), values[:, 0].min(), values[:, -1].min(),
                                values[:, :, 0].min(), values[:, :, -1].min()) <= 0:
        raise PGCDataError("implicit surface is empty or touches the meshing box; enlarge the box")
    verts, faces, _, _ = marching_cubes(values, level=0.0, spacing=(spacing,) * 3)
    verts = verts + lo
    faces = faces.astype(np.int64)
    return orient_outward(verts.astype(np.float64), faces)


def _grid(lo: np.ndarray, shape: np.ndarray, spacing: float) -> np.ndarray:
    axes = [lo[i] + spacing * np.arange(shape[i]) for i in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3).astype(np.float32)


def _sample_narrow_band(field_fn, lo: np.ndarray, hi: np.ndarray, spacing: float, factor: int = 4) -> np.ndarray:
    """Field values on the grid of ``spacing``, evaluated exactly only within a band around the surface
    found on a grid ``factor`` times coarser (elsewhere the coarse value, whose sign is right because the
    field is about 1-Lipschitz)."""
    shape = np.ceil((hi - lo) / spacing).astype(int) + 1
    coarse_shape = -(-shape // factor) + 1
    coarse = field_fn(_grid(lo, coarse_shape, spacing * factor)).reshape(coarse_shape)
    idx = [np.minimum(np.rint(np.arange(n) / factor).astype(int), m - 1) for n, m in zip(shape, coarse_shape)]
    values = coarse[np.ix_(*idx)].astype(np.float32)
    near = np.abs(values) < 1.5 * spacing * factor
    fine = _grid(lo, shape, spacing)[near.reshape(-1)]
    values[near] = field_fn(fine)
    return values


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    v = vertices[faces]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def orient_outward(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flip a closed mesh's faces if its signed volume is negative."""
    return (vertices, faces[:, ::-1].copy()) if signed_volume(vertices, faces) < 0 else (vertices, faces)


def remesh(vertices: np.ndarray, faces: np.ndarray, edge_length: float, iterations: int = 6,
           merge: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic remeshing to ``edge_length`` metres (pymeshlab), keeping the largest component.

    Open boundaries are kept in place; vertices closer than ``merge`` x ``edge_length`` are merged
    afterwards (a larger value removes slivers along the boundaries); the result is deterministic for a
    given input.
    """
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, np.float64),
                               face_matrix=np.asarray(faces, np.int32)))
    ms.meshing_isotropic_explicit_remeshing(iterations=iterations, targetlen=pymeshlab.PureValue(edge_length),
                                            featuredeg=60.0, maxsurfdist=pymeshlab.PureValue(edge_length * 0.2))
    _drop_degenerate(ms, pymeshlab, merge * edge_length)
    m = ms.current_mesh()
    return largest_component(m.vertex_matrix().astype(np.float64), m.face_matrix().astype(np.int64))


def _drop_degenerate(ms, pymeshlab, tolerance: float) -> None:
    """Merge vertices closer than ``tolerance`` metres (the remesher can leave near-duplicates along open
    boundaries) and remove the null-area and duplicate faces this leaves."""
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(tolerance))
    ms.meshing_remove_null_faces()
    ms.meshing_remove_duplicate_faces()
    ms.meshing_remove_unreferenced_vertices()


def largest_component(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edge-connected component with the most faces, unused vertices dropped."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(vertices)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    face_label = label[faces[:, 0]]
    keep = face_label == np.bincount(face_label).argmax()
    faces = faces[keep]
    used = np.unique(faces)
    remap = np.full(n, -1, np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces]


def clip_mesh(vertices: np.ndarray, faces: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep the part of a triangle mesh where the per-vertex scalar ``s`` < 0, cutting triangles exactly
    along the zero isoline of the linearly interpolated ``s`` (cut edges get one shared new vertex)."""
    s = np.where(s == 0, 1e-12, s)
    inside = s < 0
    new_vertices = [np.asarray(vertices, float)]
    edge_vertex: dict[tuple[int, int], int] = {}
    count = len(vertices)

    def cut(i: int, j: int) -> int:
        nonlocal count
        key = (min(i, j), max(i, j))
        if key not in edge_vertex:
            t = s[key[0]] / (s[key[0]] - s[key[1]])
            new_vertices.append((vertices[key[0]] + t * (vertices[key[1]] - vertices[key[0]]))[None])
            edge_vertex[key] = count
            count += 1
        return edge_vertex[key]

    n_in = inside[faces].sum(axis=1)
    out = [faces[n_in == 3]]
    for f in faces[(n_in == 1) | (n_in == 2)]:
        k = int(np.argmax(inside[f] if inside[f].sum() == 1 else ~inside[f]))
        a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]  # a is the odd one out, orientation kept
        ab, ac = cut(a, b), cut(a, c)
        if inside[a]:
            out.append(np.array([[a, ab, ac]]))
        else:
            out.append(np.array([[ab, b, c], [ab, c, ac]]))
    return largest_component(np.concatenate(new_vertices), np.concatenate(out).astype(np.int64))
