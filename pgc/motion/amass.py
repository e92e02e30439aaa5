"""SMPL-family pose clips in AMASS's npz layout, read as a :class:`~pgc.motion.clip.Clip`.

An AMASS file holds ``poses`` (T, 3 K) axis-angle rotations of K joints in SMPL's order (K = 24 for SMPL, 52
for SMPL+H, 55 for SMPL-X), ``trans`` (T, 3) root translations in metres, the frame rate (``mocap_framerate``,
or SMPL-X's ``mocap_frame_rate``) and optionally ``betas``, the subject's shape. Its world is Z-up.

The clip keeps SMPL's 22 body joints (the first 22 of every member of the family: fingers, jaw and eyes do not
move a garment). Its skeleton is the configured ``smplx`` body's at the clip's betas, so the rest pose is the
SMPL T-pose whose joint axes are world-aligned, as :mod:`pgc.motion.clip` asks: SMPL's local rotations are the
clip's as they are. The root rotation and translation are turned from AMASS's Z-up world into PGC's Y-up one.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.clip import Clip, Skeleton
from pgc.motion.rotations import axis_angle_to_matrix

if TYPE_CHECKING:
    from pgc.roles.body_model import BodyModel

SMPL_BODY_JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle", "right_ankle",
    "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")
"""SMPL's 22 body joints, in the order of its pose vector (smplx's ``JOINT_NAMES[:22]``)."""
SMPL_BODY_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
"""Parent of each of :data:`SMPL_BODY_JOINTS` (SMPL's kinematic tree)."""
JOINT_COUNTS = {24: "SMPL", 52: "SMPL+H", 55: "SMPL-X"}
"""Joints per pose vector -> the family member that writes it."""
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rotation taking AMASS's Z-up world to PGC's Y-up one (x stays, z becomes y)."""
FRAME_RATE_KEYS = ("mocap_framerate", "mocap_frame_rate")
FIX = ("an AMASS-layout npz needs 'poses' (T, 3 K) with K = 24, 52 or 55, 'trans' (T, 3) and 'mocap_framerate'; "
       "export one with AMASS's tools or numpy.savez")


def is_pose_npz(path: str | Path) -> bool:
    """Whether ``path`` is an existing ``.npz`` holding a ``poses`` array (an AMASS-layout clip, not a motion
    file of body vertices); an unreadable file is not (the motion-file reader reports what is wrong with it)."""
    import zipfile

    path = Path(path)
    if path.suffix.lower() != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return "poses" in z.files
    except (OSError, ValueError, zipfile.BadZipFile):
        return False


def read_amass(path: str | Path, body: "BodyModel", fps: float | None = None) -> Clip:
    """The clip of the AMASS-layout npz at ``path`` on the skeleton of ``body`` (the ``smplx`` body model at the
    clip's betas, clamped to the model's range); ``fps`` overrides the file's frame rate."""
    path = Path(path)
    poses, trans, rate, betas = read_pose_arrays(path)
    rate = rate if fps is None else float(fps)
    if not (np.isfinite(rate) and 0 < rate <= 1000):
        raise PGCDataError(f"{path}: frame rate {rate} must be in (0, 1000] frames per second; give --clip-fps")
    if tuple(body.joint_names[:22]) != SMPL_BODY_JOINTS:
        raise PGCDataError(f"{path}: an AMASS pose clip needs an SMPL-family body model for its skeleton (the "
                           f"configured one has joints {', '.join(body.joint_names[:4])}, ...); set [body_model] "
                           "use = \"smplx\" with its model_path (docs/body.md)")
    shape = {name: float(np.clip(b, body.parameters[name].low, body.parameters[name].high))
             for name, b in zip(body.parameters, betas)}
    rest = body.rig(shape).joints[:22]
    parents = np.array(SMPL_BODY_PARENTS)
    offsets = rest - np.where(parents[:, None] >= 0, rest[np.maximum(parents, 0)], 0.0)
    local = axis_angle_to_matrix(poses.reshape(len(poses), -1, 3)[:, :22])
    local[:, 0] = Z_UP_TO_Y_UP @ local[:, 0]
    # SMPL turns the body about its rest root and adds trans: the root lands at rest + trans, turned to Y-up.
    root_translation = (rest[0] + trans) @ Z_UP_TO_Y_UP.T - rest[0]
    return Clip(Skeleton(SMPL_BODY_JOINTS, parents, offsets), root_translation, local, rate, source=str(path))


def read_pose_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """``poses`` (T, 3 K), ``trans`` (T, 3), the frame rate and ``betas`` (possibly empty) of an AMASS npz."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files if k in ("poses", "trans", "betas", *FRAME_RATE_KEYS)}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise PGCDataError(f"{path}: not a readable npz ({exc}); {FIX}") from None
    missing = [k for k in ("poses", "trans") if k not in arrays]
    rate_key = next((k for k in FRAME_RATE_KEYS if k in arrays), None)
    if missing or rate_key is None:
        raise PGCDataError(f"{path}: missing {', '.join(missing + ([] if rate_key else ['mocap_framerate']))}; "
                           f"{FIX}")
    poses = np.asarray(arrays["poses"], np.float64)
    trans = np.asarray(arrays["trans"], np.float64)
    if poses.ndim != 2 or len(poses) == 0:
        raise PGCDataError(f"{path}: field 'poses' has shape {poses.shape}; it needs one row per frame and at least "
                           f"one frame; {FIX}")
    if poses.shape[1] % 3 or poses.shape[1] // 3 not in JOINT_COUNTS:
        raise PGCDataError(f"{path}: field 'poses' has {poses.shape[1]} values a frame; an SMPL-family pose has "
                           f"3 x {', '.join(f'{k} ({n})' for k, n in JOINT_COUNTS.items())}; {FIX}")
    if trans.shape != (len(poses), 3):
        raise PGCDataError(f"{path}: field 'trans' has shape {trans.shape}, not ({len(poses)}, 3) for its "
                           f"{len(poses)} frames of 'poses'")
    rate = np.asarray(arrays[rate_key], np.float64)
    if rate.size != 1:
        raise PGCDataError(f"{path}: field '{rate_key}' must be one number (frames per second)")
    betas = np.asarray(arrays.get("betas", np.zeros(0)), np.float64).reshape(-1)
    for name, a in (("poses", poses), ("trans", trans), ("betas", betas)):
        bad = ~np.isfinite(a.reshape(len(a), -1)).all(axis=1) if a.ndim > 1 else ~np.isfinite(a)
        if bad.any():
            raise PGCDataError(f"{path}: field '{name}' holds NaN or infinite values (first at row "
                               f"{int(np.argmax(bad))}); repair or cut those frames")
    return poses, trans, float(rate.reshape(())), betas
