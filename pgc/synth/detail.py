"""Near-field garment detail finer than the simulation mesh: knit relief, ribbed hem/cuff/neck bands, raised
seams, a patch pocket with thickness, small folds.

The detail is a fine surface *embedded* in the garment: every simulation triangle is split into ``level``^2
triangles on its barycentric lattice, and every fine vertex is its parent triangle, its barycentric
coordinates and an offset (metres) along the interpolated vertex normal. :meth:`DetailSurface.vertices`
places it on any pose of the garment (rest, simulated, rigidly moved), so ground-truth renders of new frames
carry the same relief. Parent faces, barycentrics and the fine topology are pure integer functions of the
garment's topology and ``level``; only the offsets are stored.

Offsets are a height field of the rest-pose position (outward only, so the relief never enters the body):

- knit ribs: vertical wales ``rib_height`` high, ``rib_period`` apart around the torso axis;
- ribbed bands: within ``band_width`` of the hem, the neckline and the sleeve ends the fabric is
  ``band_height`` thicker (a folded hem) with ribs across the edge, ``band_rib_period`` apart;
- seams: a ridge ``seam_height`` high and ``seam_width`` wide along the coronal plane (side seams, shoulder
  seams, under- and over-arm seams, where a front and a back panel are sewn);
- a patch pocket on the left chest: a plate ``pocket_thickness`` thick with steep side walls (2 mm), bulging
  to 1.6 times that in its middle, a rolled edge all round and a stitch groove inside its sides and bottom;
- folds: sparse horizontal ridges up to ``fold_height`` from anisotropic value noise (seeded).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.embedded import DetailSurface, embedded_points
from pgc.synth.fabrics import smoothstep, value_noise
from pgc.types import Mesh


@dataclass(frozen=True)
class DetailSpec:
    """Sizes of the near-field detail, metres."""

    edge: float = 0.002
    """Target edge length of the fine surface."""
    rib_period: float = 0.010
    rib_height: float = 0.0025
    band_width: float = 0.03
    band_height: float = 0.002
    band_rib_period: float = 0.008
    band_rib_height: float = 0.002
    seam_width: float = 0.008
    seam_height: float = 0.003
    pocket_size: tuple[float, float] = (0.11, 0.12)
    """Pocket width and height."""
    pocket_thickness: float = 0.004
    fold_height: float = 0.006
    fold_cell: tuple[float, float] = (0.10, 0.03)
    """Noise cell across (x, z) and along y of the folds."""


DETAILS: dict[str, DetailSpec | None] = {"none": None, "relief": DetailSpec(),
                                         "seams": DetailSpec(rib_height=0.0)}
"""Detail levels by name: 'none' (the simulation mesh alone), 'relief' (everything), 'seams' (everything
but the knit wales: for fleece and woven fabrics)."""


WALE_RADIUS = 0.16
"""Radius (metres) at which the knit wales' angular spacing around the torso axis equals ``rib_period``."""


def get_detail(name: str) -> DetailSpec | None:
    """The detail level ``name`` of :data:`DETAILS` (None for 'none'), else a clear error listing them."""
    if name not in DETAILS:
        raise PGCDataError(f"unknown detail '{name}' (pgc synth --detail, or a preset's detail); use one of: "
                          f"{', '.join(DETAILS)}")
    return DETAILS[name]


# ------------------------------------------------------------------------------------------ height field


def _ribs(coordinate: np.ndarray, period: float) -> np.ndarray:
    """Rounded ribs in [0, 1]: 1 on the crest of each wale, 0 in the purl valley."""
    return np.sqrt(0.5 + 0.5 * np.cos(2 * np.pi * coordinate / period))


class DetailField:
    """The detail's height field over the rest garment (see the module docstring)."""

    def __init__(self, garment: Mesh, spec: DetailSpec, seed: int) -> None:
        from scipy.spatial import cKDTree

        from pgc.synth.garments import boundary_loops

        self.spec, self.seed = spec, seed
        v = garment.vertices
        torso = v[np.abs(v[:, 0]) < 0.1]
        self.z0 = float(0.5 * (torso[:, 2].min() + torso[:, 2].max())) if len(torso) else float(v[:, 2].mean())
        y_lo, y_hi = float(v[:, 1].min()), float(v[:, 1].max())
        chest = min(0.3 * y_lo + 0.7 * y_hi, y_hi - 0.13)
        w, h = spec.pocket_size
        self.pocket = (0.045, chest - h + 0.03, 0.045 + w, chest + 0.03)  # x0, y0, x1, y1
        # the edges (hem, neckline, sleeve ends) as dense polylines with a rib coordinate along each
        points, along = [], []
        for loop in boundary_loops(garment):
            p = v[np.append(loop, loop[0])]
            seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
            length = float(seg.sum())
            if length < spec.band_rib_period:  # a degenerate loop (coincident vertices): no band to rib
                continue
            n = max(int(np.ceil(length / 0.001)), 8)
            s = np.linspace(0, length, n, endpoint=False)
            cum = np.concatenate([[0.0], np.cumsum(seg)])
            i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
            t = ((s - cum[i]) / np.maximum(seg[i], 1e-12))[:, None]
            points.append(p[i] * (1 - t) + p[i + 1] * t)
            period = length / max(round(length / spec.band_rib_period), 1)  # a whole number of ribs per loop
            along.append(s / period)
        self._edge_tree = cKDTree(np.concatenate(points)) if points else None
        self._edge_along = np.concatenate(along) if along else np.zeros(0)
        circumference = 2 * np.pi * WALE_RADIUS
        self._rib_period = circumference / max(round(circumference / spec.rib_period), 1)  # whole wales around

    def height(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(N,) outward offset (metres, >= 0) at rest ``points`` (N, 3) with unit rest ``normals`` (N, 3)."""
        s, p = self.spec, np.asarray(points, np.float64)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        # folds: sparse horizontal ridges
        cell = np.array([s.fold_cell[0], s.fold_cell[1], s.fold_cell[0]])
        folds = s.fold_height * smoothstep(0.5, 0.85, value_noise(p / cell, 1.0, self.seed + 7))
        # knit wales around the torso axis
        angle = np.arctan2(x, z - self.z0) * WALE_RADIUS  # arc length (m) around the torso axis
        ribs = s.rib_height * _ribs(angle, self._rib_period)
        # ribbed bands along the edges
        if self._edge_tree is not None:
            dist, idx = self._edge_tree.query(p)
            band = 1.0 - smoothstep(s.band_width - 0.0015, s.band_width, dist)
            band_relief = s.band_height + s.band_rib_height * _ribs(self._edge_along[idx], 1.0)
            relief = ribs * (1 - band) + band_relief * band
        else:
            relief = ribs
        # seams along the coronal plane
        seam = s.seam_height * np.sqrt(np.clip(1 - ((z - self.z0) / (0.5 * s.seam_width)) ** 2, 0.0, 1.0))
        # the patch pocket (front, left chest): a plate with steep walls that bulges a little, a rolled edge
        # all round and a stitch groove inside its sides and bottom
        x0, y0, x1, y1 = self.pocket
        inside = np.minimum(np.minimum(x - x0, x1 - x), y - y0)  # metres from the stitched edges
        edge = np.minimum(inside, y1 - y)  # metres from any edge
        plate = smoothstep(0.0, 0.002, edge) * (normals[:, 2] > 0.35) * (z > self.z0)
        bulge = np.sin(np.pi * np.clip((x - x0) / (x1 - x0), 0, 1)) * np.sin(np.pi * np.clip((y - y0) / (y1 - y0),
                                                                                              0, 1))
        piping = np.exp(-(((edge - 0.003) / 0.0015) ** 2))  # a rolled edge all round, the opening included
        groove = np.exp(-(((inside - 0.007) / 0.001) ** 2))
        pocket = plate * (s.pocket_thickness * (1.0 + 0.6 * bulge + 0.6 * piping - 0.5 * groove))
        return folds + relief + seam + pocket


def make_detail(garment: Mesh, spec: DetailSpec, seed: int) -> tuple[DetailSurface, DetailField]:
    """The detail surface of ``garment`` (rest pose, with UVs) and its height field."""
    if garment.uv is None or garment.face_uv is None:
        raise PGCDataError(f"garment '{garment.name}' has no UVs; the detail surface needs its UV atlas")
    edge = garment.vertices[garment.edges()]
    mean_edge = float(np.linalg.norm(edge[:, 1] - edge[:, 0], axis=1).mean())
    level = int(max(1, np.ceil(mean_edge / spec.edge)))
    field = DetailField(garment, spec, seed)
    surface = DetailSurface(level, np.zeros(0), garment.faces, garment.uv, garment.face_uv)
    surface.offset = root_offsets(field, garment, surface.face, surface.bary)
    return surface, field


def root_offsets(field: DetailField, garment: Mesh, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(N,) detail height at points (``face``, ``bary``) of the rest ``garment``: where fibres are rooted."""
    vn = garment.vertex_normals()
    normals = np.einsum("nk,nkd->nd", bary, vn[garment.faces[face]])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-20)
    return field.height(embedded_points(garment.vertices, garment.faces, face, bary), normals).astype(np.float32)
