"""Cloth constraint topology: stretch and bending distance constraints, masses, graph colouring (numpy).

Every constraint is a distance constraint ``C = |x_i - x_j| - L`` with its own compliance (m/N):
stretch springs on the mesh edges and bending springs between the two vertices opposite each interior
edge (the paper's "spring constraints for stretching and bending").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pgc.errors import PGCDataError
from pgc.types import Mesh

STRETCH, BEND = 0, 1


@dataclass(frozen=True)
class ClothModel:
    """Arrays of one garment, ready for a backend. Float64, indices int64."""

    rest_positions: np.ndarray
    """(V, 3) rest-shape positions (m)."""
    faces: np.ndarray
    """(F, 3) triangles."""
    inv_mass: np.ndarray
    """(V,) inverse masses (1/kg); 0 pins a vertex."""
    ci: np.ndarray
    """(C,) first vertex of each constraint."""
    cj: np.ndarray
    """(C,) second vertex of each constraint."""
    rest: np.ndarray
    """(C,) rest lengths (m)."""
    compliance: np.ndarray
    """(C,) compliance alpha (m/N) = 1 / stiffness."""
    kind: np.ndarray
    """(C,) STRETCH or BEND."""
    colours: tuple[np.ndarray, ...]
    """Constraint indices per colour: no two constraints of one colour share a vertex."""
    jacobi_share: np.ndarray
    """(C,) 1 / max(constraints at i, constraints at j): the Jacobi averaging of each constraint."""

    @property
    def num_vertices(self) -> int:
        return len(self.rest_positions)

    def with_rest(self, rest: np.ndarray) -> ClothModel:
        """The same model with new rest lengths (the sag-free solve changes only these)."""
        return replace(self, rest=np.asarray(rest, dtype=np.float64))


def bending_pairs(faces: np.ndarray) -> np.ndarray:
    """(B, 2) the two vertices opposite each interior (two-face) edge; non-manifold edges are skipped."""
    f = np.asarray(faces, dtype=np.int64)
    # half-edge k of face t runs f[t, k] -> f[t, k+1]; its opposite vertex is f[t, k+2]
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    opp = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    key = np.minimum(a, b) * (f.max(initial=0) + 1) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, opp = key[order], opp[order]
    _, start, count = np.unique(key, return_index=True, return_counts=True)
    two = start[count == 2]
    pairs = np.stack([opp[two], opp[two + 1]], axis=1)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    return np.unique(np.sort(pairs, axis=1), axis=0) if len(pairs) else np.zeros((0, 2), np.int64)


def vertex_masses(vertices: np.ndarray, faces: np.ndarray, density: float) -> np.ndarray:
    """(V,) lumped masses (kg): a third of each adjacent triangle's area times ``density`` (kg/m^2).

    Vertices with no area (isolated, or only on degenerate triangles) get 1e-3 of the mean mass so that
    every free vertex has a finite inverse mass.
    """
    v = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    mass = np.zeros(len(vertices))
    for k in range(3):
        np.add.at(mass, faces[:, k], density * area / 3.0)
    floor = 1e-3 * (mass.mean() if mass.sum() > 0 else density * 1e-4)
    return np.maximum(mass, floor)


def colour_constraints(ci: np.ndarray, cj: np.ndarray, num_vertices: int) -> tuple[np.ndarray, ...]:
    """Greedy graph colouring: constraints of one colour share no vertex. Returns indices per colour."""
    used = np.zeros(num_vertices, dtype=object)  # python ints as unbounded bitmasks of used colours
    used[:] = 0
    colour = np.empty(len(ci), dtype=np.int64)
    for c, (i, j) in enumerate(zip(ci.tolist(), cj.tolist())):
        taken = used[i] | used[j]
        k = (~taken & (taken + 1)).bit_length() - 1  # lowest free colour
        colour[c] = k
        used[i] |= 1 << k
        used[j] |= 1 << k
    return tuple(np.flatnonzero(colour == k) for k in range(int(colour.max(initial=-1)) + 1))


def build_cloth_model(mesh: Mesh, density: float, stretch_stiffness: float, bend_stiffness: float,
                      pinned: np.ndarray | None = None) -> ClothModel:
    """Constraints, masses and colouring of ``mesh`` taken as the rest shape.

    Stiffnesses in N/m; a stiffness of ``inf`` gives zero compliance (rigid). ``bend_stiffness`` 0 drops the
    bending springs. ``pinned``: vertex indices with zero inverse mass.
    """
    if len(mesh.faces) == 0:
        raise PGCDataError(f"garment mesh '{mesh.name}': no faces; the simulator needs a triangle mesh")
    x = mesh.vertices
    edges = mesh.edges()
    edges = edges[edges[:, 0] != edges[:, 1]]
    bends = bending_pairs(mesh.faces) if bend_stiffness > 0 else np.zeros((0, 2), np.int64)
    pairs = np.concatenate([edges, bends])
    kind = np.concatenate([np.full(len(edges), STRETCH), np.full(len(bends), BEND)]).astype(np.int8)
    compliance = np.where(kind == STRETCH, 1.0 / stretch_stiffness,
                          1.0 / bend_stiffness if bend_stiffness > 0 else 0.0)
    ci, cj = pairs[:, 0].copy(), pairs[:, 1].copy()
    rest = np.linalg.norm(x[ci] - x[cj], axis=1)
    inv_mass = 1.0 / vertex_masses(x, mesh.faces, density)
    if pinned is not None:
        inv_mass[np.asarray(pinned, dtype=np.int64)] = 0.0
    count = np.bincount(np.concatenate([ci, cj]), minlength=len(x))
    share = 1.0 / np.maximum(np.maximum(count[ci], count[cj]), 1)
    return ClothModel(x.copy(), mesh.faces.copy(), inv_mass, ci, cj, rest, compliance.astype(np.float64),
                      kind, colour_constraints(ci, cj, len(x)), share)
