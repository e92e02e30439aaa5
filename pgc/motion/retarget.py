"""Retargeting a clip onto a body rig, resampling it and starting it from the capture pose.

A rig is plain arrays (joint names, parents, rest joint positions), so any body model's skeleton serves. Rig
motions use the conventions of :mod:`pgc.roles.body_model`: local rotations in world-aligned rest axes
(identity = the rig's rest pose, the capture pose), the root rotating about its own rest position, plus a
root translation.

Retargeting copies global bone orientations: each mapped rig joint ``j`` (clip joint ``c``) gets
``G_j(t) = G_c(t) @ A_j``, with ``A_j`` the rest-pose rotation taking the rig's bone direction (to its first
mapped child) onto the clip's, so bones point where the clip's point whatever the two rest poses are (CMU's
T-pose onto an A-pose body). Unmapped rig joints follow their parent. The root's translation is the clip's,
scaled by the ratio of the two root heights above the feet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.clip import Clip, forward_kinematics
from pgc.motion.joint_maps import resolve_joint_map
from pgc.motion.rotations import (axis_rotation, matrix_to_quaternion, quaternion_to_matrix, rotation_aligning,
                                  slerp)

DEFAULT_RAMP_S = 0.5
"""Seconds over which a clip blends in from the capture pose (a smoothstep)."""


@dataclass(frozen=True)
class Rig:
    """A body's skeleton as plain arrays."""

    names: tuple[str, ...]
    parents: np.ndarray
    """(J,) parent indices, -1 for the root (index 0); parents come first."""
    rest: np.ndarray
    """(J, 3) rest (capture-pose) joint positions, metres."""

    def offsets(self) -> np.ndarray:
        """(J, 3) rest offsets from the parents (the root's: its rest position)."""
        parents = np.asarray(self.parents)
        return self.rest - np.where(parents[:, None] >= 0, self.rest[np.maximum(parents, 0)], 0.0)


@dataclass(frozen=True)
class RigMotion:
    """A motion of a rig: local rotations and a root translation per frame."""

    rotations: np.ndarray
    """(T, J, 3, 3) local rotations (identity = rest pose)."""
    root_translation: np.ndarray
    """(T, 3) metres added to the root's rest position."""
    fps: float

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    def joint_positions(self, rig: Rig) -> np.ndarray:
        """(T, J, 3) posed joint positions, metres."""
        return forward_kinematics(np.asarray(rig.parents), rig.offsets(), self.rotations, self.root_translation)[1]


def _root_height(rest: np.ndarray, root: int = 0) -> float:
    """Height of the root above the lowest rest joint (the feet), metres."""
    return float(rest[root, 1] - rest[:, 1].min())


def retarget(clip: Clip, rig: Rig, joint_map: dict[str, str] | None = None) -> RigMotion:
    """``clip`` on ``rig`` (global orientations copied through ``joint_map``, clip joint -> rig joint; default:
    :func:`pgc.motion.joint_maps.resolve_joint_map`). Same frames and rate as the clip."""
    mapping = resolve_joint_map(clip.skeleton.names, tuple(rig.names), clip.source, joint_map)
    to_clip = {r: clip.skeleton.index(c) for c, r in mapping.items()}
    parents = np.asarray(rig.parents)
    clip_global, _ = clip.global_transforms()
    clip_rest = clip.skeleton.rest_positions()
    T, J = clip.num_frames, len(rig.names)
    align = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    for j, name in enumerate(rig.names):
        if name not in to_clip or parents[j] < 0:
            continue
        child = next((k for k in range(j + 1, J) if parents[k] == j and rig.names[k] in to_clip), None)
        if child is None:
            align[j] = align[parents[j]]  # a leaf keeps its rest relation to its parent bone
            continue
        align[j] = rotation_aligning(rig.rest[child] - rig.rest[j],
                                     clip_rest[to_clip[rig.names[child]]] - clip_rest[to_clip[name]])
    global_rot = np.empty((T, J, 3, 3))
    local = np.empty((T, J, 3, 3))
    for j, name in enumerate(rig.names):
        p = parents[j]
        if name in to_clip:
            global_rot[:, j] = clip_global[:, to_clip[name]] @ align[j]
        else:
            global_rot[:, j] = global_rot[:, p] if p >= 0 else np.eye(3)
        local[:, j] = global_rot[:, j] if p < 0 else np.swapaxes(global_rot[:, p], -1, -2) @ global_rot[:, j]
    root_clip = to_clip[rig.names[0]]
    clip_root_rest = clip_rest[root_clip]
    clip_root = clip.joint_positions()[:, root_clip]
    clip_height = _root_height(clip_rest, root_clip)
    if clip_height <= 1e-6:
        raise PGCDataError(f"{clip.source}: joints: the clip's root '{clip.skeleton.names[root_clip]}' is not above "
                           "its other joints in the rest pose; is +Y up in the clip?")
    scale = _root_height(rig.rest) / clip_height
    return RigMotion(local, scale * (clip_root - clip_root_rest), clip.fps)


def resample(motion: RigMotion, fps: float) -> RigMotion:
    """``motion`` at ``fps`` over the same duration (frame k at k / fps seconds, up to the last source frame):
    rotations by slerp, the translation linearly."""
    if not (np.isfinite(fps) and fps > 0):
        raise PGCDataError(f"resample: frame rate {fps} must be a finite positive number")
    duration = (motion.num_frames - 1) / motion.fps
    t = np.arange(int(np.floor(duration * fps + 1e-9)) + 1) / fps
    s = np.minimum(t * motion.fps, motion.num_frames - 1)
    i0 = np.minimum(np.floor(s).astype(np.int64), max(motion.num_frames - 2, 0))
    i1 = np.minimum(i0 + 1, motion.num_frames - 1)
    frac = s - i0
    q = matrix_to_quaternion(motion.rotations)
    rot = quaternion_to_matrix(slerp(q[i0], q[i1], np.broadcast_to(frac[:, None], q[i0].shape[:-1])))
    trans = motion.root_translation[i0] * (1 - frac[:, None]) + motion.root_translation[i1] * frac[:, None]
    return RigMotion(rot, trans, float(fps))


def trim(motion: RigMotion, seconds: float | None) -> RigMotion:
    """The first ``seconds`` of ``motion`` (all of it when None or longer)."""
    if seconds is None:
        return motion
    frames = int(np.floor(seconds * motion.fps + 1e-9)) + 1
    return RigMotion(motion.rotations[:frames], motion.root_translation[:frames], motion.fps)


def start_at_capture(motion: RigMotion, rig: Rig, ramp_s: float = DEFAULT_RAMP_S) -> RigMotion:
    """``motion`` moved to start at the rig's rest pose (the capture pose, where the capture stands).

    Its frame-0 heading (turn about +Y) and horizontal place are removed, so it starts facing +Z at the rest
    position; its height is set so the lowest joint over the whole motion comes as low as the lowest rest
    joint (the feet stay on the capture's floor); it blends in from the rest pose over ``ramp_s`` seconds
    (smoothstep weight ``w``: rotations ``slerp(I, R, w)``, translation ``w x``).
    """
    forward = motion.rotations[0, 0] @ np.array([0.0, 0.0, 1.0])
    yaw = np.arctan2(forward[0], forward[2])
    c, s = np.cos(yaw), np.sin(yaw)
    heading = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # a turn by -yaw about +Y
    rotations = motion.rotations.copy()
    rotations[:, 0] = heading @ rotations[:, 0]
    translation = (motion.root_translation - motion.root_translation[0]) @ heading.T
    translation[:, 1] = motion.root_translation[:, 1]
    lowest = RigMotion(rotations, translation, motion.fps).joint_positions(rig)[..., 1].min()
    translation[:, 1] += rig.rest[:, 1].min() - lowest
    t = np.arange(motion.num_frames) / motion.fps
    x = np.clip(t / ramp_s, 0.0, 1.0) if ramp_s > 0 else np.ones_like(t)
    w = x * x * (3 - 2 * x)
    q = matrix_to_quaternion(rotations)
    identity = np.zeros_like(q)
    identity[..., 0] = 1.0
    rotations = quaternion_to_matrix(slerp(identity, q, np.broadcast_to(w[:, None], q.shape[:-1])))
    return RigMotion(rotations, translation * w[:, None], motion.fps)


ARM_SPACE_DEG = 15.0
"""Least angle (degrees) between a hanging upper arm and the chest's down axis, seen from the front, after
retargeting (like the "arm space" of common retargeting tools). A clip's arms hang closer to its actor's torso
than a broader body allows: copied as they are, the upper arms pass through the body's chest and pinch the
garment (measured in docs/simulation.md)."""
SHOULDERS: dict[str, float] = {"lhumerus": 1.0, "rhumerus": -1.0, "LeftArm": 1.0, "RightArm": -1.0}
"""Upper-arm joints of the known rigs, with the side (+1: the person's left, +X)."""


def in_place(motion: RigMotion) -> RigMotion:
    """The motion with its root held over the capture position: the horizontal (x, z) root translation removed,
    the height kept, so that a walk or a run stays in front of fixed cameras (a treadmill's view)."""
    translation = motion.root_translation.copy()
    translation[:, [0, 2]] = 0.0
    return RigMotion(motion.rotations, translation, motion.fps)


def keep_arms_clear(motion: RigMotion, rig: Rig, min_deg: float = ARM_SPACE_DEG) -> RigMotion:
    """``motion`` with each hanging upper arm (the rig's joints among :data:`SHOULDERS`) turned outward about the
    chest's forward axis where, seen from the front, it is less than ``min_deg`` from the chest's down axis.
    The chest is the shoulder's grandparent (the clavicle's parent); the rest of the arm follows."""
    parents = np.asarray(rig.parents)
    rotations = motion.rotations.copy()
    global_rot, pos = forward_kinematics(parents, rig.offsets(), rotations, motion.root_translation)
    for name, side in SHOULDERS.items():
        if name not in rig.names:
            continue
        j = rig.names.index(name)
        child = next((k for k in range(j + 1, len(rig.names)) if parents[k] == j), None)
        if child is None or parents[j] < 0 or parents[parents[j]] < 0:
            continue
        clavicle, chest = parents[j], parents[parents[j]]
        d = np.einsum("tba,tb->ta", global_rot[:, chest], pos[:, child] - pos[:, j])  # in the chest's axes
        angle = np.arctan2(side * d[:, 0], -d[:, 1])  # from the down axis, outward positive
        deficit = np.where(d[:, 1] < 0, np.maximum(0.0, np.deg2rad(min_deg) - angle), 0.0)
        deficit = np.where(angle < -np.pi / 2, 0.0, deficit)  # an arm across the body is left alone
        turn = global_rot[:, chest] @ axis_rotation("Z", side * deficit) @ np.swapaxes(global_rot[:, chest], -1, -2)
        shoulder = turn @ global_rot[:, j]
        rotations[:, j] = np.swapaxes(global_rot[:, clavicle], -1, -2) @ shoulder
    return RigMotion(rotations, motion.root_translation, motion.fps)
