"""An SMPL-like parametric body made here: capsule primitives around the skeleton's bones, meshed as one
smooth closed surface, with smooth linear-blend-skinning weights.

Construction: smooth union of tapered elliptic capsules (torso parts flattened front-to-back) -> marching
cubes -> isotropic remeshing (roughly uniform triangles of ``edge_length``) -> skinning weights from the
distance to each bone's surface, softened and diffused over the mesh, summing to 1.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from pgc.errors import PGCDataError
from pgc.synth import implicit
from pgc.synth.implicit import Capsule
from pgc.synth.skeleton import JOINTS, PARENTS, BodyShape, global_transforms, joint_index, rest_joints
from pgc.types import Mesh

BLEND = 0.012
"""Smooth-union blend radius as a fraction of the height."""


@dataclass
class BodyModel:
    """A skinned body in the capture A-pose (the rest pose)."""

    vertices: np.ndarray
    """(V, 3) float64 rest (A-pose) positions, metres."""
    faces: np.ndarray
    """(F, 3) int64, counter-clockwise seen from outside; the surface is closed and 2-manifold."""
    joints: np.ndarray
    """(J, 3) rest joint positions."""
    parents: np.ndarray
    """(J,) parent indices (-1 for the root)."""
    weights: np.ndarray
    """(V, J) skinning weights, non-negative, rows sum to 1."""
    shape: BodyShape = field(default_factory=BodyShape)
    parts: tuple[Capsule, ...] = ()
    """The capsules the surface was built from (rest pose), each with its joint."""
    joint_names: tuple[str, ...] = JOINTS

    def pose(self, joint_rotations: np.ndarray) -> np.ndarray:
        """Linear blend skinning: local joint rotations (J, 3, 3) or (T, J, 3, 3) -> vertices (V, 3) or
        (T, V, 3). Identity rotations give the rest pose."""
        transforms = global_transforms(self.joints, self.parents, joint_rotations)
        blended = np.einsum("vj,...jab->...vab", self.weights, transforms[..., :3, :])
        return np.einsum("...vab,vb->...va", blended[..., :3], self.vertices) + blended[..., 3]

    def mesh(self, vertices: np.ndarray | None = None) -> Mesh:
        """The body as a :class:`Mesh` (label 1 on every face), at rest or at the given vertices."""
        v = self.vertices if vertices is None else vertices
        return Mesh(v, self.faces, face_labels=np.ones(len(self.faces), np.int32), name="body")

    def field(self, points: np.ndarray) -> np.ndarray:
        """Approximate signed distance (metres, negative inside) of the rest-pose implicit body."""
        return implicit.smooth_union([implicit.capsule_field(points, c) for c in self.parts],
                                     BLEND * self.shape.height)


def body_parts(shape: BodyShape) -> tuple[Capsule, ...]:
    """The capsules of the body in the A-pose, each bound to the joint that moves it."""
    j = rest_joints(shape)
    h, g = shape.height, shape.girth

    def at(name: str) -> np.ndarray:
        return j[joint_index(name)]

    def cap(a, b, ra, rb, joint, depth=1.0) -> Capsule:
        return Capsule(tuple(map(float, a)), tuple(map(float, b)), ra, rb, joint_index(joint), depth)

    sw = shape.shoulder_width / 2
    parts = [
        cap(at("pelvis") + [-0.045 * h, 0.005 * h, 0], at("pelvis") + [0.045 * h, 0.005 * h, 0],
            0.07 * h * g, 0.07 * h * g, "pelvis", 0.78),
        cap(at("pelvis"), at("spine2"), 0.074 * h * g, 0.074 * h * g, "spine1", 0.68),
        cap(at("spine2"), at("spine3"), 0.078 * h * g, 0.083 * h * g, "spine2", 0.66),
        cap([-(sw - 0.025 * h), 0.79 * h, -0.012], [sw - 0.025 * h, 0.79 * h, -0.012],
            0.043 * h * g, 0.043 * h * g, "spine3", 0.95),
        cap(at("neck") + [0, -0.03 * h, 0], at("head"), 0.033 * h, 0.031 * h, "neck"),
        cap(at("head") + [0, 0.025 * h, 0.012 * h], at("head") + [0, 0.068 * h, 0.0], 0.05 * h, 0.053 * h,
            "head", 0.95),
    ]
    for side in ("l", "r"):
        parts += [
            cap(at(f"{side}_shoulder"), at(f"{side}_elbow"), 0.031 * h * g, 0.024 * h * g, f"{side}_shoulder"),
            cap(at(f"{side}_elbow"), at(f"{side}_wrist"), 0.023 * h * g, 0.017 * h * g, f"{side}_elbow"),
            cap(at(f"{side}_wrist"), at(f"{side}_hand"), 0.017 * h, 0.015 * h, f"{side}_wrist", 0.7),
            cap(at(f"{side}_hip"), at(f"{side}_knee"), 0.05 * h * g, 0.033 * h * g, f"{side}_hip"),
            cap(at(f"{side}_knee"), at(f"{side}_ankle"), 0.031 * h * g, 0.021 * h * g, f"{side}_knee"),
            cap(at(f"{side}_ankle"), at(f"{side}_foot"), 0.021 * h, 0.018 * h, f"{side}_ankle", 0.8),
        ]
    return tuple(parts)


def skinning_weights(vertices: np.ndarray, faces: np.ndarray, parts: tuple[Capsule, ...], num_joints: int,
                     softness: float, smoothing_steps: int = 6) -> np.ndarray:
    """(V, J) weights: softmax of minus the distance to each joint's part surfaces (temperature
    ``softness`` metres), then Laplacian diffusion over the mesh; non-negative rows summing to 1."""
    dist = np.full((len(vertices), num_joints), np.inf)
    for c in parts:
        dist[:, c.joint] = np.minimum(dist[:, c.joint], implicit.capsule_field(vertices, c))
    logits = -(dist - dist.min(axis=1, keepdims=True)) / softness
    w = np.exp(logits)
    w /= w.sum(axis=1, keepdims=True)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    degree = np.bincount(e.ravel(), minlength=len(vertices)).astype(float)
    for _ in range(smoothing_steps):
        acc = np.zeros_like(w)
        np.add.at(acc, e[:, 0], w[e[:, 1]])
        np.add.at(acc, e[:, 1], w[e[:, 0]])
        w = 0.5 * w + 0.5 * acc / degree[:, None]
    w[w < 1e-4] = 0.0
    return w / w.sum(axis=1, keepdims=True)


@functools.lru_cache(maxsize=8)
def _build(shape: BodyShape, edge_length: float) -> BodyModel:
    parts = body_parts(shape)
    joints = rest_joints(shape)
    k = BLEND * shape.height

    def field_fn(p: np.ndarray) -> np.ndarray:
        return implicit.smooth_union([implicit.capsule_field(p, c) for c in parts], k)

    margin = 0.15 * shape.height  # the top of the head is 0.12 h above the head joint
    lo, hi = joints.min(axis=0) - margin, joints.max(axis=0) + margin
    spacing = float(np.clip(edge_length / 2.0, 0.006, 0.016)) * shape.height / 1.7  # marching-cubes grid
    v, f = implicit.mesh_field(field_fn, lo, hi, spacing)
    v, f = implicit.remesh(v, f, edge_length)
    v, f = implicit.orient_outward(v, f)
    _check_closed(f)
    weights = skinning_weights(v, f, parts, len(JOINTS), softness=0.012 * shape.height)
    return BodyModel(v, f, joints, PARENTS.copy(), weights, shape, parts)


def _check_closed(faces: np.ndarray) -> None:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    if not np.all(counts == 2):
        raise PGCDataError(f"synthetic body mesh is not closed 2-manifold ({np.sum(counts != 2)} bad edges); "
                           "try another edge_length")


def make_body(shape: BodyShape | None = None, edge_length: float = 0.022) -> BodyModel:
    """The body for ``shape`` (default: average adult, 1.70 m) meshed with ~``edge_length`` metre edges
    (0.022 gives about 4k vertices). Cached: returns a fresh copy of the cached arrays."""
    if not 0.005 <= edge_length <= 0.08:
        raise PGCDataError(f"make_body: edge_length {edge_length} m is outside [0.005, 0.08]")
    b = _build(shape or BodyShape(), float(edge_length))
    return BodyModel(b.vertices.copy(), b.faces.copy(), b.joints.copy(), b.parents.copy(), b.weights.copy(),
                     b.shape, b.parts)
