"""The synthetic capture's body: a body of the ``body_model`` role (default: Anny) with a phenotype drawn per
seed, in the capture pose (the rig's rest A-pose), as plain arrays that pose themselves by linear blend
skinning and give a signed distance field for fitting garments.

Conventions: those of :mod:`pgc.roles.body_model` (metres, +Y up, facing +Z, the person's left at +X, feet on
y = 0; local rotations in world-aligned rest axes, identity = the capture pose).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles.body_model import global_transforms
from pgc.types import Mesh

if TYPE_CHECKING:
    from pgc.motion.retarget import Rig
    from pgc.roles.body_model import BodyModel

PLAUSIBLE_PHENOTYPE: dict[str, tuple[float, float]] = {
    "gender": (0.0, 1.0), "age": (0.6, 0.9), "muscle": (0.25, 0.75), "weight": (0.25, 0.75),
    "height": (0.2, 0.6), "proportions": (0.2, 0.8),
}
"""Ranges each seed draws Anny's phenotypes from (uniformly): adults (25 to about 60 years) of 1.5-2.0 m, from
slim to heavy (docs/synth.md has the measured heights). Other body models' parameters are drawn from the
middle third of their range around the default."""

SURFACE_SAMPLES = 40_000
"""Points sampled on the body surface (about 7 mm apart on an adult) to find each point's nearest triangle."""
CANDIDATES = 4
"""Triangles (of the nearest samples or vertices) among which the field finds the closest point."""

GARMENT_JOINTS: dict[str, str] = {
    "pelvis": "Hips", "waist": "LowerBack", "chest": "Spine", "upper_chest": "Spine1", "neck": "Neck",
    "l_shoulder": "LeftArm", "r_shoulder": "RightArm", "l_elbow": "LeftForeArm", "r_elbow": "RightForeArm",
}
"""Landmarks the garments and motions use -> joints of the ``cmu_mb`` rig (Anny's)."""


def draw_phenotype(body_model: BodyModel, seed: int) -> dict[str, float]:
    """The shape of ``seed``'s body: each of ``body_model``'s parameters drawn uniformly from
    :data:`PLAUSIBLE_PHENOTYPE` (or the middle third of its range), rounded to 1e-4."""
    rng = np.random.default_rng([seed, 0x80D7])
    shape = {}
    for name, spec in body_model.parameters.items():
        third = (spec.high - spec.low) / 6
        middle = (max(spec.low, spec.default - third), min(spec.high, spec.default + third))
        lo, hi = PLAUSIBLE_PHENOTYPE.get(name, middle)
        shape[name] = round(float(rng.uniform(lo, hi)), 4)
    return body_model.check_shape(shape)


@dataclass
class SynthBody:
    """A skinned body in the capture pose (the rig's rest pose)."""

    model: str
    """The body model that made it (its class name)."""
    phenotype: dict[str, float]
    """Its shape parameters."""
    vertices: np.ndarray
    """(V, 3) float64 rest positions, metres."""
    faces: np.ndarray
    """(F, 3) int64, counter-clockwise seen from outside."""
    joints: np.ndarray
    """(J, 3) rest joint positions."""
    parents: np.ndarray
    """(J,) int64 parent indices (-1 for the root)."""
    weights: np.ndarray
    """(V, J) skinning weights, rows summing to 1."""
    joint_names: tuple[str, ...]
    _tree: object = field(default=None, repr=False, compare=False)

    @property
    def height(self) -> float:
        """Standing height (top of the head above the floor), metres."""
        return float(self.vertices[:, 1].max())

    def joint(self, name: str) -> np.ndarray:
        """Rest position (3,) of joint ``name`` (a rig joint or a :data:`GARMENT_JOINTS` landmark)."""
        rig_name = GARMENT_JOINTS.get(name, name)
        if rig_name not in self.joint_names:
            raise PGCDataError(f"the {self.model} body has no joint '{rig_name}'; the synthetic garments and motions "
                               f"need the joints of Anny's cmu_mb rig ({', '.join(GARMENT_JOINTS.values())})")
        return self.joints[self.joint_names.index(rig_name)]

    def rig(self) -> Rig:
        """The skeleton as a :class:`pgc.motion.retarget.Rig`."""
        from pgc.motion.retarget import Rig

        return Rig(tuple(self.joint_names), np.asarray(self.parents), np.asarray(self.joints, np.float64))

    def pose(self, rotations: np.ndarray, translation: np.ndarray | None = None) -> np.ndarray:
        """Linear blend skinning: local rotations (J, 3, 3) or (T, J, 3, 3) and a root translation (3,) or
        (T, 3) -> vertices (V, 3) or (T, V, 3). Identity rotations give the capture pose."""
        transforms = global_transforms(self.joints, self.parents, rotations, translation)
        blended = np.einsum("vj,...jab->...vab", self.weights, transforms[..., :3, :])
        return np.einsum("...vab,vb->...va", blended[..., :3], self.vertices) + blended[..., 3]

    def mesh(self, vertices: np.ndarray | None = None) -> Mesh:
        """The body as a :class:`Mesh` named 'body' (label 1 on every face), at rest or at ``vertices``."""
        v = self.vertices if vertices is None else vertices
        return Mesh(v, self.faces, face_labels=np.ones(len(self.faces), np.int32), name="body")

    def field(self, points: np.ndarray, exact_within: float = 0.1) -> np.ndarray:
        """Signed distance (metres, negative inside) of ``points`` (N, 3) to the rest surface: the distance to
        the closest of the triangles of the :data:`CANDIDATES` nearest surface samples (within ``exact_within``
        metres; farther, of the nearest vertices: an over-estimate by at most the gap to the truly nearest
        triangle), signed by the interpolated vertex normal there. (A nearest-neighbour query far from a
        surface visits most of its samples, so the bound keeps the field fast.)"""
        from pgc.arrays import array_ops
        from pgc.sim.collision import vertex_normals
        from pgc.sim.xpbd import closest_contact

        if self._tree is None:
            self._tree = _surface_samples(self.vertices, self.faces)
        points = np.asarray(points, np.float64)
        (tree, face), (vertex_tree, vertex_face) = self._tree
        d, i = tree.query(points, k=CANDIDATES, distance_upper_bound=exact_within)
        far = ~np.isfinite(d[:, 0])
        candidates = np.empty((len(points), CANDIDATES), np.int64)
        candidates[~far] = face[np.minimum(i[~far], len(face) - 1)]  # misses repeat the nearest sample's face
        candidates[~far] = np.where(np.isfinite(d[~far]), candidates[~far], candidates[~far][:, :1])
        candidates[far] = vertex_face[vertex_tree.query(points[far], k=CANDIDATES)[1]]
        contact = closest_contact(array_ops("numpy"), points, self.vertices,
                                  vertex_normals(self.vertices, self.faces), self.faces[candidates])
        return np.where(contact.signed < 0, -1.0, 1.0) * np.linalg.norm(points - contact.point, axis=1)


def _surface_samples(vertices: np.ndarray, faces: np.ndarray):
    """((KD-tree of area-uniform surface samples, the face of each), (KD-tree of the vertices, a face of each));
    deterministic."""
    from scipy.spatial import cKDTree

    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rng = np.random.default_rng(0)
    face = rng.choice(len(faces), SURFACE_SAMPLES, p=area / area.sum())
    u, v = rng.random((2, SURFACE_SAMPLES))
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    t = tri[face]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    vertex_face = np.zeros(len(vertices), np.int64)
    vertex_face[faces.ravel()] = np.repeat(np.arange(len(faces)), 3)
    return (cKDTree(points), face), (cKDTree(vertices), vertex_face)


def make_body(body_model: BodyModel, phenotype: dict[str, float] | None = None) -> SynthBody:
    """The body of ``body_model`` with ``phenotype`` (default: the model's defaults) in the capture pose."""
    b = _cached(body_model, tuple(sorted(body_model.check_shape(phenotype).items())))
    return SynthBody(b.model, dict(b.phenotype), b.vertices.copy(), b.faces.copy(), b.joints.copy(), b.parents.copy(),
                     b.weights.copy(), b.joint_names)


@functools.lru_cache(maxsize=8)
def _cached(body_model: BodyModel, shape: tuple[tuple[str, float], ...]) -> SynthBody:
    """The body of one shape (cached per model and shape; callers copy its arrays)."""
    state = body_model.forward(dict(shape))
    return SynthBody(type(body_model).__name__, dict(shape), state.vertices, np.asarray(state.faces, np.int64),
                     state.joints, np.asarray(body_model.parents, np.int64), np.asarray(body_model.weights, np.float64),
                     tuple(body_model.joint_names))

