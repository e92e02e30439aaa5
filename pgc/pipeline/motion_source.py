"""``--motion`` resolved: a captured clip or a built-in motion on the capture's body (the synthetic capture's
body model), or a motion file of body vertices. Pipeline-side because built-in motions and the capture's body
come from the generator (:mod:`pgc.synth`), which the core never imports."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError
from pgc.motion.drive import SHIPPED_PREFIX, ClipOptions, clip_body_motion, is_clip, shipped_clip
from pgc.types import BodyMotion


def resolve_motion(spec: str, capture_dir: Path | None, seconds: float | None = None,
                   clip: ClipOptions = ClipOptions(), pose_body: Callable[[], Any] | None = None) -> BodyMotion:
    """The BodyMotion of ``--motion SPEC``: a clip (.amc/.bvh file or ``cmu:NAME``, on the capture's body), a
    motion file (npz or OBJ folder) or a built-in motion name (on the capture's body). ``pose_body`` makes the
    configured body model, which an AMASS pose clip needs for its skeleton (called only for one)."""
    from pgc.synth.motions import MOTIONS, make_motion

    path = shipped_clip(spec) if spec.startswith(SHIPPED_PREFIX) else Path(spec)
    if is_clip(path) and not path.is_file():
        raise PGCDataError(f"{path}: clip file not found")
    if path.exists() and not is_clip(path):
        from pgc.io.motion import load_motion

        return load_motion(path)
    if not is_clip(path) and spec not in MOTIONS:
        raise PGCDataError(f"motion '{spec}' is neither a file nor a built-in motion ({', '.join(MOTIONS)}); "
                           "clips are .amc or .bvh files")
    what = f"clip '{spec}'" if is_clip(path) else f"built-in motion '{spec}'"
    if capture_dir is None or not (capture_dir / "ground_truth").is_dir():
        raise PGCDataError(f"{what} needs the body model of a synthetic capture; the asset records none. Pass "
                           "--capture DIR, or give a motion file of body vertices (npz or OBJ folder)")
    from pgc.synth.ground_truth import read_body_model

    body = read_body_model(capture_dir)
    if is_clip(path):
        from pgc.motion.amass import is_pose_npz

        skeleton_body = pose_body() if pose_body is not None and is_pose_npz(path) else None
        return clip_body_motion(path, body, clip, seconds, pose_body=skeleton_body)
    return make_motion(body, spec, seconds=seconds)
