"""Captured clips on a body: from a clip file (or a shipped ``cmu:NAME``) to a :class:`BodyMotion`.

A clip (``.amc`` with its ASF, ``.bvh``, an AMASS-layout SMPL pose ``.npz`` on the ``smplx`` body's skeleton) is
retargeted onto the body's rig, resampled to :data:`SIM_FPS`, cut
to ``seconds``, moved to start in the capture pose (blending in over :data:`~pgc.motion.retarget.DEFAULT_RAMP_S`),
its hanging upper arms kept :data:`~pgc.motion.retarget.ARM_SPACE_DEG` from the chest, and skinned with the
body's weights.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.clip import Clip
from pgc.types import BodyMotion

CLIP_SUFFIXES = (".amc", ".bvh")
"""File suffixes read as captured clips."""
SIM_FPS = 30.0
"""Frame rate clips are resampled to: the paper's 30 fps, that of the built-in motions."""
SHIPPED_PREFIX = "cmu:"
"""``--motion cmu:02_01`` names a clip shipped in ``pgc/data/motions/cmu`` (``.amc`` unless a suffix is given)."""


def shipped_clips() -> Path:
    """The folder of the shipped CMU clips (with their credit, README.md)."""
    return Path(__file__).resolve().parent.parent / "data" / "motions" / "cmu"


def shipped_clip(spec: str) -> Path:
    """The file of a shipped clip named ``cmu:NAME`` (``NAME.amc`` unless NAME has a clip suffix)."""
    name = spec[len(SHIPPED_PREFIX):]
    path = shipped_clips() / (name if Path(name).suffix.lower() in CLIP_SUFFIXES else f"{name}.amc")
    if not path.is_file():
        names = sorted(p.name for p in shipped_clips().iterdir() if p.suffix in CLIP_SUFFIXES)
        raise PGCDataError(f"motion '{spec}': no shipped clip {path.name}; shipped: {', '.join(names)}")
    return path


@dataclass(frozen=True)
class ClipOptions:
    """How to read a clip: an AMC's skeleton and frame rate, a BVH's length unit (None: the defaults), and whether
    it moves in place."""

    skeleton: Path | None = None
    """The ASF of an AMC (default: the subject's beside it, ``02_01.amc`` -> ``02.asf``)."""
    fps: float | None = None
    """Frame rate of the clip (AMC default: CMU's 120; BVH default: its Frame Time)."""
    unit_m: float | None = None
    """Metres per BVH length unit (default: centimetres)."""
    joint_map: Path | None = None
    """A JSON file of clip joint -> rig joint names (default: the known map that fits both skeletons)."""
    in_place: bool = False
    """Hold the root over the capture position (:func:`pgc.motion.retarget.in_place`): a walk stays in view of
    the capture's fixed cameras."""


EVALUATED_CLIP = ClipOptions(in_place=True)
"""How ``pgc demo`` and the sweeps read a clip that they evaluate: in place, since their ground truth is seen by the
capture's fixed cameras, which a walk would leave."""


def is_clip(spec: str | Path) -> bool:
    """Whether ``--motion SPEC`` names a captured clip (a .amc or .bvh file, ``cmu:NAME``, or an .npz of SMPL
    poses in AMASS's layout)."""
    from pgc.motion.amass import is_pose_npz

    return str(spec).startswith(SHIPPED_PREFIX) or Path(spec).suffix.lower() in CLIP_SUFFIXES or is_pose_npz(spec)


def load_clip(path: str | Path, options: ClipOptions = ClipOptions(), pose_body=None) -> Clip:
    """The clip of an ``.amc`` (on its ASF), a ``.bvh`` file or an AMASS-layout pose ``.npz`` (on the skeleton of
    ``pose_body``, the configured ``smplx`` body model)."""
    from dataclasses import replace

    from pgc.motion.amass import is_pose_npz, read_amass

    path = Path(path)
    suffix = path.suffix.lower()
    if is_pose_npz(path):
        if options.skeleton is not None or options.unit_m is not None:
            raise PGCDataError(f"{path}: an AMASS pose clip's skeleton and units come from the SMPL model; "
                               "--skeleton and --clip-unit are for .amc and .bvh clips")
        if pose_body is None:
            raise PGCDataError(f"{path}: an AMASS pose clip needs the smplx body model for its skeleton; set "
                               "[body_model] use = \"smplx\" with its model_path (docs/body.md)")
        return read_amass(path, pose_body, options.fps)
    if suffix in CLIP_SUFFIXES and not path.is_file():
        raise PGCDataError(f"{path}: clip file not found")
    if options.fps is not None and not (np.isfinite(options.fps) and 0 < options.fps <= 1000):
        raise PGCDataError(f"{path}: clip frame rate {options.fps} must be in (0, 1000] frames per second")
    if suffix == ".amc":
        if options.unit_m is not None:
            raise PGCDataError(f"{path}: a length unit is for BVH files; an AMC's comes from its ASF (:units length)")
        from pgc.motion.asf import read_amc_clip

        return read_amc_clip(path, options.skeleton, options.fps)
    if suffix == ".bvh":
        if options.skeleton is not None:
            raise PGCDataError(f"{path}: a BVH file holds its own skeleton; --skeleton is for .amc clips")
        from pgc.motion.bvh import DEFAULT_UNIT_M, read_bvh

        clip = read_bvh(path, options.unit_m or DEFAULT_UNIT_M)
        return clip if options.fps is None else replace(clip, fps=float(options.fps))
    raise PGCDataError(f"{path}: not a clip; captured clips are .amc (with their .asf), .bvh files or AMASS "
                       "pose .npz files")


def clip_body_motion(path: str | Path, body, options: ClipOptions = ClipOptions(), seconds: float | None = None,
                     arm_space_deg: float | None = None, pose_body=None) -> BodyMotion:
    """The vertices of ``body`` (joint names, parents, rest joints, faces and a ``pose(rotations, translation)``
    that skins them, as :class:`pgc.synth.body.SynthBody` has) driven by the clip at ``path``, at
    :data:`SIM_FPS`, frame 0 the capture pose; ``seconds`` cuts the clip (default: all of it);
    ``arm_space_deg``: see :func:`pgc.motion.retarget.keep_arms_clear` (None: its default; 0: arms as captured);
    ``pose_body``: the ``smplx`` body model that an AMASS pose clip needs for its skeleton."""
    from pgc.motion.joint_maps import read_joint_map
    from pgc.motion.retarget import (ARM_SPACE_DEG, Rig, in_place, keep_arms_clear, resample, retarget,
                                      start_at_capture, trim)

    clip = load_clip(path, options, pose_body)
    joint_map = None if options.joint_map is None else read_joint_map(options.joint_map)
    rig = Rig(tuple(body.joint_names), np.asarray(body.parents), np.asarray(body.joints, np.float64))
    motion = start_at_capture(trim(resample(retarget(clip, rig, joint_map), SIM_FPS), seconds), rig)
    if options.in_place:
        motion = in_place(motion)
    space = ARM_SPACE_DEG if arm_space_deg is None else arm_space_deg
    if space > 0:
        motion = keep_arms_clear(motion, rig, space)
    vertices = body.pose(motion.rotations, motion.root_translation)
    return BodyMotion(vertices.astype(np.float32), body.faces, fps=motion.fps, name=Path(path).stem)
