"""Body motions as joint-rotation sequences that start in the capture A-pose (frame 0 = rest pose).

Each motion eases from the A-pose into its target (a smoothstep over ``ramp`` seconds) and then holds or
cycles, so a simulator can start from the capture pose without a jump. Rotations are local axis-angle
vectors in the rest pose's world-aligned axes (see :mod:`pgc.synth.skeleton`); +Z is forward.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.synth.skeleton import A_POSE_ARM_DEG, JOINTS, joint_index, rotation_between
from pgc.types import BodyMotion

PoseFn = Callable[[np.ndarray], np.ndarray]
"""Times (T,) seconds -> axis-angle poses (T, J, 3)."""

_A = np.deg2rad(A_POSE_ARM_DEG)


def _arm_dir(side: str) -> np.ndarray:
    s = 1.0 if side == "l" else -1.0
    return np.array([s * np.cos(_A), -np.sin(_A), 0.0])


def _mirror(aa: np.ndarray) -> np.ndarray:
    """Axis-angle of the left-right mirrored rotation (reflection x -> -x)."""
    return np.array([aa[0], -aa[1], -aa[2]])


def _ease(t: np.ndarray, ramp: float) -> np.ndarray:
    x = np.clip(t / ramp, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _static(targets: dict[str, np.ndarray], ramp: float = 1.0) -> PoseFn:
    """Ease into fixed left-side targets (mirrored onto the right side for names starting with 'l_')."""
    def fn(t: np.ndarray) -> np.ndarray:
        pose = np.zeros((len(t), len(JOINTS), 3))
        w = _ease(t, ramp)[:, None]
        for name, aa in targets.items():
            pose[:, joint_index(name)] = w * aa
            if name.startswith("l_"):
                pose[:, joint_index("r_" + name[2:])] = w * _mirror(aa)
        return pose
    return fn


def _goalpost() -> PoseFn:
    """Upper arms horizontal to the sides, forearms vertical (elbows bent 90 degrees up)."""
    return _static({"l_shoulder": rotation_between(_arm_dir("l"), [1, 0, 0]),
                    "l_elbow": np.array([0, 0, np.pi / 2])})


def _spooky() -> PoseFn:
    """Both arms straight forward at shoulder height."""
    return _static({"l_shoulder": rotation_between(_arm_dir("l"), [0.15, 0, 1]),
                    "l_elbow": np.array([-0.15, 0, 0])})


def _arms_up() -> PoseFn:
    """Upside-down U: arms raised above the head, forearms curving in towards each other."""
    return _static({"l_shoulder": rotation_between(_arm_dir("l"), [0.45, 0.89, 0.05]),
                    "l_elbow": np.array([0, 0, 0.9])}, ramp=1.2)


def _cyclic(period: float, fill: Callable[[np.ndarray, np.ndarray, np.ndarray], None]) -> PoseFn:
    """A periodic motion: ``fill(pose, amplitude, phase)`` writes axis-angles into ``pose`` (T, J, 3); the
    amplitude eases in from 0 over 0.6 s so the motion starts in the A-pose."""
    def fn(t: np.ndarray) -> np.ndarray:
        pose = np.zeros((len(t), len(JOINTS), 3))
        fill(pose, _ease(t, 0.6), 2 * np.pi * t / period)
        return pose
    return fn


def _walk(period: float = 1.1) -> PoseFn:
    """Walking in place: hips swing +-25 degrees, knees flex in the swing phase, arms swing opposite."""
    def fill(pose: np.ndarray, amp: np.ndarray, phase: np.ndarray) -> None:
        for side, sgn in (("l", 1.0), ("r", -1.0)):
            swing = sgn * np.sin(phase)
            pose[:, joint_index(f"{side}_hip"), 0] = -amp * np.deg2rad(25) * swing
            knee = np.maximum(0.0, sgn * np.sin(phase + 1.2))
            pose[:, joint_index(f"{side}_knee"), 0] = amp * np.deg2rad(45) * knee
            pose[:, joint_index(f"{side}_shoulder"), 0] = amp * np.deg2rad(20) * swing
            pose[:, joint_index(f"{side}_elbow"), 0] = -amp * np.deg2rad(15) * (1 + 0.5 * swing)
        pose[:, joint_index("spine2"), 1] = amp * np.deg2rad(5) * np.sin(phase)
    return _cyclic(period, fill)


def _arm_swing(period: float = 1.4) -> PoseFn:
    """Both arms swing forward and back (+-50 degrees at the shoulder) in opposite phase."""
    def fill(pose: np.ndarray, amp: np.ndarray, phase: np.ndarray) -> None:
        for side, sgn in (("l", 1.0), ("r", -1.0)):
            pose[:, joint_index(f"{side}_shoulder"), 0] = -amp * np.deg2rad(50) * sgn * np.sin(phase)
            pose[:, joint_index(f"{side}_elbow"), 0] = -amp * np.deg2rad(20) * (1 - np.cos(phase)) / 2
    return _cyclic(period, fill)


MOTION_FNS: dict[str, tuple[Callable[[], PoseFn], float]] = {
    "goalpost": (_goalpost, 2.0),
    "spooky": (_spooky, 2.0),
    "arms-up": (_arms_up, 2.5),
    "walk": (_walk, 3.0),
    "arm-swing": (_arm_swing, 3.0),
}
MOTIONS: tuple[str, ...] = tuple(MOTION_FNS)
"""Names of the built-in motions."""


def motion_rotations(name: str, seconds: float | None = None, fps: float = 30.0) -> np.ndarray:
    """Local joint rotations (T, J, 3, 3) of motion ``name``; frame 0 is the A-pose (identity)."""
    if name not in MOTION_FNS:
        raise PGCDataError(f"unknown motion '{name}'; motions: {', '.join(MOTIONS)}")
    make, default_seconds = MOTION_FNS[name]
    seconds = default_seconds if seconds is None else float(seconds)
    if seconds <= 0 or fps <= 0:
        raise PGCDataError(f"motion '{name}': seconds ({seconds}) and fps ({fps}) must be positive")
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    return axis_angle_to_matrix(make()(t))


def make_motion(body, name: str, seconds: float | None = None, fps: float = 30.0) -> BodyMotion:
    """The skinned body vertices of motion ``name`` at ``fps`` (frame 0 = the capture A-pose).

    ``body`` is a :class:`pgc.synth.body.BodyModel`; ``seconds`` defaults to the motion's own length.
    """
    vertices = body.pose(motion_rotations(name, seconds, fps))
    return BodyMotion(vertices.astype(np.float32), body.faces, fps=fps, name=name)
