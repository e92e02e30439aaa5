"""``--motion`` resolved: a captured clip or a built-in motion on the capture's body (the synthetic capture's
body model, or for a capture without ground truth the body that ``pgc reconstruct`` fitted to it), or a motion
file of body vertices. Pipeline-side because built-in motions and the capture's body
come from the generator (:mod:`pgc.synth`), which the core never imports."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.motion.drive import SHIPPED_PREFIX, ClipOptions, clip_body_motion, is_clip, shipped_clip
from pgc.types import BodyMotion


def resolve_motion(spec: str, capture_dir: Path | None, seconds: float | None = None,
                   clip: ClipOptions = ClipOptions(), pose_body: Callable[[], Any] | None = None,
                   fitted_body_dir: Path | None = None) -> BodyMotion:
    """The BodyMotion of ``--motion SPEC``: a clip (.amc/.bvh file or ``cmu:NAME``, on the capture's body), a
    motion file (npz or OBJ folder) or a built-in motion name (on the capture's body). The capture's body is its
    ground truth's, else the fitted body in ``fitted_body_dir`` (an asset's ``body_fit``). ``pose_body`` makes
    the configured body model, which an AMASS pose clip needs for its skeleton (called only for one)."""
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
    body = capture_body(capture_dir, fitted_body_dir, what)
    if is_clip(path):
        from pgc.motion.amass import is_pose_npz

        skeleton_body = pose_body() if pose_body is not None and is_pose_npz(path) else None
        return clip_body_motion(path, body, clip, seconds, pose_body=skeleton_body)
    return make_motion(body, spec, seconds=seconds)


def capture_body(capture_dir: Path | None, fitted_body_dir: Path | None, what: str):
    """The skinned body in the capture pose that motions move: a synthetic capture's true body, else the body
    fitted to the capture (``fitted_body_dir/body.json``, re-based so that its fitted pose is the rest pose)."""
    if capture_dir is not None and (capture_dir / "ground_truth").is_dir():
        from pgc.synth.ground_truth import read_body_model

        return read_body_model(capture_dir)
    if fitted_body_dir is not None and (fitted_body_dir / "body.json").is_file():
        return fitted_body(fitted_body_dir)
    raise PGCDataError(f"{what} needs the capture's body: a synthetic capture's ground truth, or the body that "
                       "'pgc reconstruct' fits to a capture without one (ASSET/body_fit). Pass --capture DIR, "
                       "reconstruct the asset again, or give a motion file of body vertices (npz or OBJ folder)")


def fitted_body(folder: Path):
    """The fitted body of ``folder/body.json`` as a skinned body whose rest pose is the fitted capture pose: its
    posed vertices and joints, the model's weights, so that identity rotations give the capture."""
    from pgc.io.body_fit import read_body_fit
    from pgc.registry import default_registry
    from pgc.synth.body import SynthBody

    fit = read_body_fit(folder)
    model = default_registry().create("body_model", fit.model, fit.options)
    if tuple(model.joint_names) != fit.joint_names:
        raise PGCDataError(f"{folder / 'body.json'}: its joints do not match the '{fit.model}' body model's; fit "
                           "the body again with 'pgc body fit' or 'pgc reconstruct'")
    posed = model.forward(fit.shape, fit.rotations, fit.translation)
    return SynthBody(fit.model, dict(fit.shape), posed.vertices, posed.faces, posed.joints,
                     np.asarray(model.parents, np.int64), np.asarray(model.weights, np.float64), fit.joint_names)
