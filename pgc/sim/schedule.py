"""The body sequence a simulation steps through: settle on the capture pose, blend in, then the motion."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError
from pgc.types import BodyMotion


@dataclass(frozen=True)
class BodySchedule:
    """Body vertices per simulated frame and which of them are the motion's frames."""

    vertices: np.ndarray
    """(N, B, 3) float64: frame 0 is the capture pose the garment starts on."""
    first_motion: int
    """Index of motion frame 0 in ``vertices``; motion frame t is ``first_motion + t``."""


def smoothstep(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def body_schedule(motion: BodyMotion, settle_frames: int, blend_frames: int,
                  capture: np.ndarray | None = None) -> BodySchedule:
    """Settle ``settle_frames`` on the capture pose, blend (smoothstep) into motion frame 0 over
    ``blend_frames`` when the capture pose differs from it, then play the motion.

    ``capture``: (B, 3) capture-pose body; default: motion frame 0 (the role's contract).
    """
    frames = motion.vertices.astype(np.float64)
    if motion.num_frames == 0:
        raise PGCDataError(f"motion '{motion.name}': no frames")
    start = frames[0] if capture is None else np.asarray(capture, dtype=np.float64)
    if start.shape != frames[0].shape:
        raise PGCDataError(f"motion '{motion.name}': capture body has {start.shape[0]} vertices, the motion "
                           f"{frames.shape[1]}; they must share one topology")
    seq = [start] * (1 + settle_frames)
    if blend_frames and np.abs(start - frames[0]).max() > 1e-6:
        for s in smoothstep(np.arange(1, blend_frames + 1) / blend_frames):
            seq.append(start + s * (frames[0] - start))
    first = len(seq)
    return BodySchedule(np.concatenate([np.stack(seq), frames]), first)
