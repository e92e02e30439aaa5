"""What is embedded in a triangle mesh and follows its deformation: points at a barycentric position in a
parent face plus an offset along the interpolated vertex normal (:func:`embedded_points`) and a fine surface
on each face's barycentric lattice (:class:`DetailSurface`); fibres rooted on faces are :mod:`pgc.geometry.fibres`.

They describe a synthetic scene's near field (:class:`pgc.roles.scene_renderer.SceneGeometry`): the generator
(:mod:`pgc.synth`) makes them, a scene renderer places them on any pose of the garment.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from pgc.types import GARMENT_LABEL, Mesh


def embedded_points(vertices: np.ndarray, faces: np.ndarray, face: np.ndarray, bary: np.ndarray,
                    offset: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) points at barycentrics ``bary`` (N, 3) of ``faces[face]`` on a garment with ``vertices``,
    moved ``offset`` (N,) metres along the interpolated area-weighted vertex normal (unit length)."""
    v = np.asarray(vertices, np.float64)
    p = np.einsum("nk,nkd->nd", bary, v[faces[face]])
    if offset is None:
        return p
    vn = Mesh(v, faces).vertex_normals()
    n = np.einsum("nk,nkd->nd", bary, vn[faces[face]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
    return p + np.asarray(offset, np.float64)[:, None] * n


def lattice(level: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric lattice of one triangle: integer weights (M, 3) on corners (a, b, c), summing to
    ``level``, and the (level^2, 3) local triangles, oriented like (a, b, c)."""
    jk = [(j, k) for j in range(level + 1) for k in range(level + 1 - j)]
    index = {p: i for i, p in enumerate(jk)}
    weights = np.array([(level - j - k, j, k) for j, k in jk], np.int64)
    tris = [(index[j, k], index[j + 1, k], index[j, k + 1]) for j, k in jk if j + k <= level - 1]
    tris += [(index[j + 1, k], index[j + 1, k + 1], index[j, k + 1]) for j, k in jk if j + k <= level - 2]
    return weights, np.array(tris, np.int64)


@dataclass
class DetailSurface:
    """A fine surface embedded in a garment of ``faces`` (and its UV atlas ``face_uv``/``uv``)."""

    level: int
    """Each garment triangle is split into level^2 triangles."""
    offset: np.ndarray
    """(N,) offset of each fine vertex along the interpolated garment normal, metres."""
    garment_faces: np.ndarray
    garment_uv: np.ndarray
    garment_face_uv: np.ndarray

    @cached_property
    def _topology(self) -> tuple[np.ndarray, ...]:
        """Parent face, barycentrics, fine faces, fine face_uv, fine uv, parent face of each fine face."""
        f = np.asarray(self.garment_faces, np.int64)
        w, tris = lattice(self.level)
        m = len(w)
        vid = np.broadcast_to(f[:, None, :], (len(f), m, 3))
        wt = np.broadcast_to(w[None], (len(f), m, 3))
        # a lattice point is the same on every face that shares it: key = its (vertex, weight) pairs, sorted
        big = np.iinfo(np.int64).max
        vk = np.where(wt > 0, vid, big)
        order = np.argsort(vk, axis=2, kind="stable")
        key = np.concatenate([np.take_along_axis(vk, order, 2), np.take_along_axis(wt, order, 2)], axis=2)
        _, first, inverse = np.unique(key.reshape(-1, 6), axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        face = (first // m).astype(np.int64)
        bary = w[first % m].astype(np.float64) / self.level
        corner = np.arange(len(f))[:, None, None] * m + tris[None]  # (F, level^2, 3) per-face lattice indices
        faces = inverse[corner].reshape(-1, 3)
        parent = np.repeat(np.arange(len(f)), len(tris))
        fuv = np.asarray(self.garment_uv, np.float64)[np.asarray(self.garment_face_uv, np.int64)]  # (F, 3, 2)
        uv = np.einsum("mk,fkd->fmd", w / self.level, fuv).reshape(-1, 2).astype(np.float32)
        return face, bary, faces, corner.reshape(-1, 3), uv, parent

    @property
    def face(self) -> np.ndarray:
        """(N,) parent garment face of each fine vertex."""
        return self._topology[0]

    @property
    def bary(self) -> np.ndarray:
        """(N, 3) barycentrics of each fine vertex in its parent face."""
        return self._topology[1]

    @property
    def faces(self) -> np.ndarray:
        """(F * level^2, 3) fine triangles (oriented like their parents)."""
        return self._topology[2]

    @property
    def parent_face(self) -> np.ndarray:
        """(F * level^2,) garment face of each fine triangle."""
        return self._topology[5]

    def vertices(self, garment_vertices: np.ndarray) -> np.ndarray:
        """(N, 3) fine vertices on the garment posed at ``garment_vertices``."""
        return embedded_points(garment_vertices, np.asarray(self.garment_faces, np.int64), self.face, self.bary,
                               self.offset)

    def mesh(self, garment_vertices: np.ndarray, name: str = "garment_detail") -> Mesh:
        """The fine surface as a :class:`Mesh` with per-corner UVs in the garment's atlas, every face labelled
        garment (:data:`pgc.types.GARMENT_LABEL`)."""
        _, _, faces, face_uv, uv, _ = self._topology
        labels = np.full(len(faces), GARMENT_LABEL, np.int32)
        return Mesh(self.vertices(garment_vertices), faces, uv, face_uv, labels, name)
