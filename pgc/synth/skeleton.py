"""The synthetic body's skeleton: joints of an SMPL-like hierarchy, shape-dependent rest positions, rotations.

Conventions: metres, +Y up, the person faces +Z, feet on y = 0, the person's left is +X. The rest pose is
the capture A-pose (arms 45 degrees below horizontal). Joint rotations are local, in world-aligned axes of the
rest pose (identity everywhere = the A-pose), so ``global_j = global_parent @ local_j``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError

JOINTS: tuple[str, ...] = (
    "pelvis", "spine1", "spine2", "spine3", "neck", "head",
    "l_clavicle", "l_shoulder", "l_elbow", "l_wrist", "l_hand",
    "r_clavicle", "r_shoulder", "r_elbow", "r_wrist", "r_hand",
    "l_hip", "l_knee", "l_ankle", "l_foot",
    "r_hip", "r_knee", "r_ankle", "r_foot",
)
PARENT_NAMES: dict[str, str | None] = {
    "pelvis": None, "spine1": "pelvis", "spine2": "spine1", "spine3": "spine2", "neck": "spine3", "head": "neck",
    "l_clavicle": "spine3", "l_shoulder": "l_clavicle", "l_elbow": "l_shoulder", "l_wrist": "l_elbow",
    "l_hand": "l_wrist",
    "r_clavicle": "spine3", "r_shoulder": "r_clavicle", "r_elbow": "r_shoulder", "r_wrist": "r_elbow",
    "r_hand": "r_wrist",
    "l_hip": "pelvis", "l_knee": "l_hip", "l_ankle": "l_knee", "l_foot": "l_ankle",
    "r_hip": "pelvis", "r_knee": "r_hip", "r_ankle": "r_knee", "r_foot": "r_ankle",
}
PARENTS: np.ndarray = np.array([-1 if PARENT_NAMES[j] is None else JOINTS.index(PARENT_NAMES[j]) for j in JOINTS],
                               dtype=np.int64)
"""(J,) parent index of each joint, -1 for the root; parents come before children."""

A_POSE_ARM_DEG = 45.0
"""Angle of the arms below the horizontal in the capture pose."""


@dataclass(frozen=True)
class BodyShape:
    """Shape parameters of the synthetic body."""

    height: float = 1.70
    """Standing height, metres (top of the head)."""
    girth: float = 1.0
    """Scale of limb and torso radii (1 = average build)."""
    shoulder_width: float = 0.36
    """Distance between the shoulder joints, metres."""

    def __post_init__(self) -> None:
        for name, lo, hi in (("height", 1.0, 2.3), ("girth", 0.6, 1.6), ("shoulder_width", 0.25, 0.5)):
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise PGCDataError(f"BodyShape.{name} = {value} is outside the supported range [{lo}, {hi}]")


def joint_index(name: str) -> int:
    """Index of joint ``name`` in :data:`JOINTS`."""
    try:
        return JOINTS.index(name)
    except ValueError:
        raise PGCDataError(f"unknown joint '{name}'; joints: {', '.join(JOINTS)}") from None


def rest_joints(shape: BodyShape) -> np.ndarray:
    """(J, 3) joint positions of the A-pose for ``shape`` (proportions of an average adult)."""
    h, half_sw = shape.height, shape.shoulder_width / 2
    hip_x = 0.052 * h * shape.girth ** 0.5
    a = np.deg2rad(A_POSE_ARM_DEG)
    arm = np.array([np.cos(a), -np.sin(a), 0.0])
    shoulder_y = 0.815 * h
    p: dict[str, np.ndarray] = {
        "pelvis": np.array([0.0, 0.53 * h, 0.0]),
        "spine1": np.array([0.0, 0.60 * h, -0.005]),
        "spine2": np.array([0.0, 0.67 * h, -0.01]),
        "spine3": np.array([0.0, 0.75 * h, -0.01]),
        "neck": np.array([0.0, 0.84 * h, -0.015]),
        "head": np.array([0.0, 0.885 * h, 0.0]),
    }
    for side, sign in (("l", 1.0), ("r", -1.0)):
        m = np.array([sign, 1.0, 1.0])
        p[f"{side}_clavicle"] = np.array([0.02, 0.80 * h, 0.0]) * m
        sh = np.array([half_sw, shoulder_y, -0.01]) * m
        p[f"{side}_shoulder"] = sh
        d = arm * np.array([sign, 1.0, 1.0])
        p[f"{side}_elbow"] = sh + 0.19 * h * d
        p[f"{side}_wrist"] = sh + 0.335 * h * d
        p[f"{side}_hand"] = sh + 0.39 * h * d
        p[f"{side}_hip"] = np.array([hip_x, 0.485 * h, 0.0]) * m
        p[f"{side}_knee"] = np.array([hip_x * 0.95, 0.285 * h, 0.01]) * m
        p[f"{side}_ankle"] = np.array([hip_x * 0.9, 0.045 * h, -0.01]) * m
        p[f"{side}_foot"] = np.array([hip_x * 0.95, 0.02 * h, 0.12 * h / 1.7]) * m
    return np.stack([p[j] for j in JOINTS])


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Axis-angle (3,) of the shortest rotation taking direction ``a`` to direction ``b``."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        if c > 0:
            return np.zeros(3)
        ortho = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        return np.pi * ortho / np.linalg.norm(ortho)
    return axis / s * np.arctan2(s, c)


def global_transforms(joints: np.ndarray, parents: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Skinning transforms (..., J, 4, 4) mapping rest-pose points to posed points, per joint.

    ``rotations`` (..., J, 3, 3) are local rotations about each joint (identity = rest pose); the root joint
    rotates about its own position, so the pose keeps the pelvis in place.
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    J = len(parents)
    if rotations.shape[-3:] != (J, 3, 3):
        raise PGCDataError(f"joint rotations must have shape (..., {J}, 3, 3), got {rotations.shape}")
    batch = rotations.shape[:-3]
    rot_g = np.empty_like(rotations)
    pos_g = np.empty(batch + (J, 3))
    for j in range(J):
        p = parents[j]
        if p < 0:
            rot_g[..., j, :, :] = rotations[..., j, :, :]
            pos_g[..., j, :] = joints[j]
        else:
            rot_g[..., j, :, :] = rot_g[..., p, :, :] @ rotations[..., j, :, :]
            offset = joints[j] - joints[p]
            pos_g[..., j, :] = pos_g[..., p, :] + np.einsum("...ab,b->...a", rot_g[..., p, :, :], offset)
    out = np.zeros(batch + (J, 4, 4))
    out[..., :3, :3] = rot_g
    out[..., :3, 3] = pos_g - np.einsum("...jab,jb->...ja", rot_g, joints)
    out[..., 3, 3] = 1.0
    return out
