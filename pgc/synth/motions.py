"""Body motions as joint-rotation sequences on the synthetic body's rig that start in the capture pose (frame 0 =
rest pose).

Each motion eases from the capture A-pose into its target (a smoothstep over ``ramp`` seconds) and then holds
or cycles, so a simulator can start from the capture pose without a jump. The paper's three test motions are
keyframes given as bone directions (upper arm and forearm, left side; the right mirrors it), turned into
rotations of the body's own rest bones, so they hold on any body shape. Rotations are local axis-angle vectors
in the rest pose's world-aligned axes (:mod:`pgc.roles.body_model`); +Z is forward, +X the person's left.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.rotations import axis_angle_to_matrix, matrix_to_quaternion, rotation_aligning
from pgc.synth.body import SynthBody
from pgc.types import BodyMotion

PoseFn = Callable[[np.ndarray], np.ndarray]
"""Times (T,) seconds -> axis-angle poses (T, J, 3)."""
SIDES = (("l", "Left", 1.0), ("r", "Right", -1.0))
"""(landmark prefix, rig word, sign of x) per side."""


def axis_angle(rotation: np.ndarray) -> np.ndarray:
    """Axis-angle vector (3,) of a rotation matrix (angle in [0, pi])."""
    q = matrix_to_quaternion(np.asarray(rotation, np.float64))
    q = q if q[0] >= 0 else -q
    s = float(np.linalg.norm(q[1:]))
    return np.zeros(3) if s < 1e-12 else q[1:] / s * 2 * np.arctan2(s, q[0])


def _ease(t: np.ndarray, ramp: float) -> np.ndarray:
    x = np.clip(t / ramp, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def arm_keyframe(body: SynthBody, upper_arm: tuple[float, float, float], forearm: tuple[float, float, float]
                 ) -> dict[str, np.ndarray]:
    """Axis-angle rotations of both arms (rig joint name -> (3,)) that point the left upper arm and forearm
    along the given directions and the right ones along their mirror images (x -> -x)."""
    out = {}
    for _, word, sign in SIDES:
        m = np.array([sign, 1.0, 1.0])
        shoulder, elbow, wrist = (body.joint(f"{word}{j}") for j in ("Arm", "ForeArm", "Hand"))
        r_shoulder = rotation_aligning(elbow - shoulder, m * upper_arm)
        r_elbow = rotation_aligning(wrist - elbow, r_shoulder.T @ (m * np.asarray(forearm, float)))
        out[f"{word}Arm"], out[f"{word}ForeArm"] = axis_angle(r_shoulder), axis_angle(r_elbow)
    return out


def _static(upper_arm: tuple[float, float, float], forearm: tuple[float, float, float], ramp: float = 1.0
            ) -> Callable[[SynthBody], PoseFn]:
    """Ease into an arm keyframe (:func:`arm_keyframe`)."""
    def make(body: SynthBody) -> PoseFn:
        targets = {body.joint_names.index(name): aa for name, aa in arm_keyframe(body, upper_arm, forearm).items()}

        def fn(t: np.ndarray) -> np.ndarray:
            pose = np.zeros((len(t), len(body.joint_names), 3))
            w = _ease(t, ramp)[:, None]
            for j, aa in targets.items():
                pose[:, j] = w * aa
            return pose
        return fn
    return make


GOALPOST = _static((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
"""Goal-post: upper arms horizontal to the sides, forearms vertical (elbows bent 90 degrees up)."""
SPOOKY = _static((0.15, 0.0, 1.0), (0.15, 0.15, 0.98))
"""Spooky: both arms straight forward at shoulder height."""
ARMS_UP = _static((0.45, 0.89, 0.05), (-0.42, 0.9, 0.05), ramp=1.2)
"""Upside-down U: arms raised above the head, forearms curving in towards each other."""


def _cyclic(period: float, fill: Callable[[np.ndarray, Callable[[str], int], np.ndarray, np.ndarray], None]
            ) -> Callable[[SynthBody], PoseFn]:
    """A periodic motion: ``fill(pose, index, amplitude, phase)`` writes axis-angles into ``pose`` (T, J, 3)
    (``index``: rig joint name -> its column); the amplitude eases in from 0 over 0.6 s so the motion starts in
    the capture pose."""
    def make(body: SynthBody) -> PoseFn:
        def fn(t: np.ndarray) -> np.ndarray:
            pose = np.zeros((len(t), len(body.joint_names), 3))
            fill(pose, body.joint_names.index, _ease(t, 0.6), 2 * np.pi * t / period)
            return pose
        return fn
    return make


def _walk(period: float = 1.1) -> Callable[[SynthBody], PoseFn]:
    """Walking in place: hips swing +-25 degrees, knees flex in the swing phase, arms swing opposite."""
    def fill(pose: np.ndarray, index, amp: np.ndarray, phase: np.ndarray) -> None:
        for _, word, sgn in SIDES:
            swing = sgn * np.sin(phase)
            pose[:, index(f"{word}UpLeg"), 0] = -amp * np.deg2rad(25) * swing
            knee = np.maximum(0.0, sgn * np.sin(phase + 1.2))
            pose[:, index(f"{word}Leg"), 0] = amp * np.deg2rad(45) * knee
            pose[:, index(f"{word}Arm"), 0] = amp * np.deg2rad(20) * swing
            pose[:, index(f"{word}ForeArm"), 0] = -amp * np.deg2rad(15) * (1 + 0.5 * swing)
        pose[:, index("Spine"), 1] = amp * np.deg2rad(5) * np.sin(phase)
    return _cyclic(period, fill)


def _arm_swing(period: float = 1.4) -> Callable[[SynthBody], PoseFn]:
    """Both arms swing forward and back (+-50 degrees at the shoulder) in opposite phase."""
    def fill(pose: np.ndarray, index, amp: np.ndarray, phase: np.ndarray) -> None:
        for _, word, sgn in SIDES:
            pose[:, index(f"{word}Arm"), 0] = -amp * np.deg2rad(50) * sgn * np.sin(phase)
            pose[:, index(f"{word}ForeArm"), 0] = -amp * np.deg2rad(20) * (1 - np.cos(phase)) / 2
    return _cyclic(period, fill)


MOTION_FNS: dict[str, tuple[Callable[[SynthBody], PoseFn], float]] = {
    "goalpost": (GOALPOST, 2.0),
    "spooky": (SPOOKY, 2.0),
    "arms-up": (ARMS_UP, 2.5),
    "walk": (_walk(), 3.0),
    "arm-swing": (_arm_swing(), 3.0),
}
MOTIONS: tuple[str, ...] = tuple(MOTION_FNS)
"""Names of the built-in motions."""


def motion_rotations(name: str, body: SynthBody, seconds: float | None = None, fps: float = 30.0) -> np.ndarray:
    """Local joint rotations (T, J, 3, 3) of motion ``name`` on ``body``'s rig; frame 0 is the capture pose
    (identity)."""
    if name not in MOTION_FNS:
        raise PGCDataError(f"unknown motion '{name}'; motions: {', '.join(MOTIONS)}")
    make, default_seconds = MOTION_FNS[name]
    seconds = default_seconds if seconds is None else float(seconds)
    if seconds <= 0 or fps <= 0:
        raise PGCDataError(f"motion '{name}': seconds ({seconds}) and fps ({fps}) must be positive")
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    return axis_angle_to_matrix(make(body)(t))


def make_motion(body, name: str, seconds: float | None = None, fps: float = 30.0) -> BodyMotion:
    """The skinned vertices of ``body`` (a :class:`pgc.synth.body.SynthBody`) in motion ``name`` at ``fps``
    (frame 0 = the capture pose); ``seconds`` defaults to the motion's own length."""
    vertices = body.pose(motion_rotations(name, body, seconds, fps))
    return BodyMotion(vertices.astype(np.float32), body.faces, fps=fps, name=name)
