"""The clip type shared by every motion-capture reader: a skeleton and per-frame joint rotations.

Conventions (those of :mod:`pgc.roles.body_model`): metres, +Y up. In the rest pose every joint rotation is the
identity and joint axes are aligned with the world's; a joint's local rotation turns its children about the
joint, ``global_j = global_parent @ local_j`` and ``position_j = position_parent + global_parent @ offset_j``.
The root joint's position is its rest offset plus the frame's root translation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.errors import PGCDataError


@dataclass(frozen=True)
class Skeleton:
    """Joints of a motion-capture skeleton in its rest pose."""

    names: tuple[str, ...]
    """(J,) unique joint names."""
    parents: np.ndarray
    """(J,) int64 parent index of each joint, -1 for the root (one root, index 0); parents come first."""
    offsets: np.ndarray
    """(J, 3) float64 rest offset of each joint from its parent, metres (the root's: its rest position)."""

    def __post_init__(self) -> None:
        J = len(self.names)
        if J == 0 or len(set(self.names)) != J:
            raise PGCDataError(f"skeleton: joint names must be unique and non-empty, got {list(self.names)}")
        parents = np.asarray(self.parents, np.int64)
        if parents.shape != (J,) or parents[0] != -1 or np.any(parents[1:] < 0) \
                or np.any(parents[1:] >= np.arange(1, J)):
            raise PGCDataError("skeleton: one root first, and every other joint after its parent")
        object.__setattr__(self, "parents", parents)
        offsets = np.asarray(self.offsets, np.float64)
        if offsets.shape != (J, 3) or not np.all(np.isfinite(offsets)):
            raise PGCDataError(f"skeleton: offsets must be finite (J, 3) metres, got {offsets.shape}")
        object.__setattr__(self, "offsets", offsets)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def rest_positions(self) -> np.ndarray:
        """(J, 3) joint positions in the rest pose, metres."""
        pos = np.zeros((len(self.names), 3))
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] + (pos[p] if p >= 0 else 0.0)
        return pos


@dataclass(frozen=True)
class Clip:
    """A captured motion: a skeleton, a root translation and local joint rotations per frame."""

    skeleton: Skeleton
    root_translation: np.ndarray
    """(T, 3) float64 translation of the root from its rest position per frame, metres."""
    rotations: np.ndarray
    """(T, J, 3, 3) float64 local joint rotations (identity = rest pose)."""
    fps: float
    """Frames per second."""
    source: str = ""
    """Where the clip came from (a file name), for messages."""

    def __post_init__(self) -> None:
        T, J = len(self.root_translation), len(self.skeleton.names)
        if T == 0:
            raise PGCDataError(f"{self.source}: the clip has zero frames; a motion needs at least one")
        if self.rotations.shape != (T, J, 3, 3) or self.root_translation.shape != (T, 3):
            raise PGCDataError(f"{self.source}: rotations {self.rotations.shape} and root translation "
                               f"{self.root_translation.shape} do not fit {T} frames of {J} joints")
        for what, arr in (("joint angles", self.rotations), ("root translation", self.root_translation)):
            bad = ~np.isfinite(arr).reshape(T, -1).all(axis=1)
            if bad.any():
                raise PGCDataError(f"{self.source}: {what} are not finite (NaN or infinite) in {int(bad.sum())} "
                                   f"frame(s), first frame {int(np.argmax(bad))} (0-based); repair or cut those "
                                   "frames in the capture software")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise PGCDataError(f"{self.source}: frame rate {self.fps} must be a finite positive number")

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics: global rotations (T, J, 3, 3) and world joint positions (T, J, 3), metres."""
        return forward_kinematics(self.skeleton.parents, self.skeleton.offsets, self.rotations, self.root_translation)

    def joint_positions(self) -> np.ndarray:
        """(T, J, 3) world joint positions per frame, metres."""
        return self.global_transforms()[1]


def forward_kinematics(parents: np.ndarray, offsets: np.ndarray, rotations: np.ndarray,
                       root_translation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (T, J, 3, 3) and positions (T, J, 3) from local rotations (T, J, 3, 3), rest offsets
    (J, 3) and root translations (T, 3) in the conventions of this module."""
    T, J = rotations.shape[:2]
    rot_g = np.empty_like(rotations)
    pos_g = np.empty((T, J, 3))
    for j, p in enumerate(parents):
        if p < 0:
            rot_g[:, j] = rotations[:, j]
            pos_g[:, j] = offsets[j] + root_translation
        else:
            rot_g[:, j] = rot_g[:, p] @ rotations[:, j]
            pos_g[:, j] = pos_g[:, p] + rot_g[:, p] @ offsets[j]
    return rot_g, pos_g
