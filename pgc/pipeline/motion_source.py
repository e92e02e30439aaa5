"""Which body a run moves on, and ``--motion`` resolved on it.

The rule (:func:`motion_body`), in this one place: an asset's garment moves on the capture's true body (a synthetic
capture's ground-truth body model) unless ``[stages.body_fit] motion_body = "fit"`` (``pgc reconstruct --body
fit``) asks for the body fitted to the capture, or the capture has no true body; then ``pgc reconstruct`` runs the
``body_fit`` stage and records ``"fit"`` in the asset (``source.body``), and ``pgc animate`` moves that body.

A motion (:class:`MotionSource`) is a captured clip or a built-in motion, made on a skinned body, or a motion file
of body vertices. Pipeline-side because built-in motions and the capture's body come from the generator
(:mod:`pgc.synth`), which the core never imports."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pgc.config import RunConfig
from pgc.errors import PGCDataError
from pgc.motion.drive import SHIPPED_PREFIX, ClipOptions, clip_body_motion, is_clip, shipped_clip
from pgc.types import BodyMotion

def has_body_truth(capture_dir: str | Path | None) -> bool:
    """Whether a capture brings its true body: a synthetic capture's ``ground_truth/body_model.npz``, the skinned
    body that motions move."""
    return capture_dir is not None and (Path(capture_dir) / "ground_truth" / "body_model.npz").is_file()


def motion_body(capture_dir: str | Path | None, asked: str) -> str:
    """The body an asset of ``capture_dir`` moves on when ``asked`` (``[stages.body_fit] motion_body``) is
    'truth' or 'fit': the true body where asked and the capture has one, else the body fitted to the capture."""
    from pgc.stages.body_fit import MOTION_BODIES

    if asked not in MOTION_BODIES:
        raise PGCDataError(f"motion body '{asked}' is unknown; use one of: {', '.join(MOTION_BODIES)}")
    return "truth" if asked == "truth" and has_body_truth(capture_dir) else "fit"


def with_motion_body(cfg: RunConfig, body: str) -> RunConfig:
    """``cfg`` with ``[stages.body_fit] motion_body = body`` (``pgc reconstruct --body``)."""
    settings = cfg.stage("body_fit")
    updated = settings.model_validate({**settings.model_dump(), "motion_body": body})
    return replace(cfg, stages={**cfg.stages, "body_fit": updated})


def asset_body(asset_config: dict[str, Any], capture_dir: Path | None) -> str:
    """The body an asset's garment moves on: the one ``pgc reconstruct`` recorded (``source.body``); an asset
    recorded without one moved on the true body where its capture has one."""
    body = asset_config.get("source", {}).get("body")
    return body if isinstance(body, str) else motion_body(capture_dir, "truth")


@dataclass(frozen=True)
class MotionSource:
    """``--motion SPEC`` with what shapes it (its length in seconds, how a clip is read): recorded in a run's
    run.json (``motion_source``), so the same motion can be made again on another body."""

    spec: str
    seconds: float | None = None
    clip: ClipOptions = ClipOptions()

    @property
    def path(self) -> Path:
        return shipped_clip(self.spec) if self.spec.startswith(SHIPPED_PREFIX) else Path(self.spec)

    @property
    def kind(self) -> str:
        """What the spec names, once checked: 'clip' (a captured clip) or 'built-in' (a built-in motion), both made
        on a body, or 'file' (a motion file of body vertices)."""
        from pgc.synth.motions import MOTIONS

        path = self.path
        if is_clip(path):
            if not path.is_file():
                raise PGCDataError(f"{path}: clip file not found")
            return "clip"
        if path.exists():
            return "file"
        if self.spec not in MOTIONS:
            raise PGCDataError(f"motion '{self.spec}' is neither a file nor a built-in motion ({', '.join(MOTIONS)}); "
                               "clips are .amc or .bvh files")
        return "built-in"

    def record(self) -> dict[str, Any]:
        """The run.json record (paths as given)."""
        clip = {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(self.clip).items()}
        return {"spec": self.spec, "kind": self.kind, "seconds": self.seconds, "clip": clip}

    @classmethod
    def from_record(cls, doc: Any, where: str) -> MotionSource:
        """The source recorded by :meth:`record`; one clear error for a malformed record."""
        fix = "animate the run again with 'pgc animate'"
        fields = set(vars(ClipOptions()))
        if (not isinstance(doc, dict) or not isinstance(doc.get("spec"), str)
                or not isinstance(doc.get("clip"), dict) or not set(doc["clip"]) <= fields):
            raise PGCDataError(f"{where}: field 'motion_source' must hold 'spec' and 'clip' "
                               f"({', '.join(sorted(fields))}); {fix}")
        clip = {k: (Path(v) if k in ("skeleton", "joint_map") and v is not None else v) for k, v in doc["clip"].items()}
        seconds = doc.get("seconds")
        if seconds is not None and not (isinstance(seconds, (int, float)) and np.isfinite(seconds) and seconds > 0):
            raise PGCDataError(f"{where}: field 'motion_source.seconds' must be a positive number or null; {fix}")
        return cls(doc["spec"], None if seconds is None else float(seconds), ClipOptions(**clip))


def resolve_motion(source: MotionSource, skinned_body: Callable[[str], Any],
                   pose_body: Callable[[], Any] | None = None) -> BodyMotion:
    """The BodyMotion of ``source``: a clip (.amc/.bvh file, ``cmu:NAME`` or AMASS pose .npz) or a built-in motion
    on ``skinned_body(what)`` (the skinned body in the capture pose, :func:`capture_body`; called only for those),
    or a motion file (npz or OBJ folder) as it is. ``pose_body`` makes the configured body model, which an AMASS
    pose clip needs for its skeleton (called only for one)."""
    kind = source.kind
    if kind == "file":
        from pgc.io.motion import load_motion

        return load_motion(source.path)
    body = skinned_body(f"clip '{source.spec}'" if kind == "clip" else f"built-in motion '{source.spec}'")
    if kind == "clip":
        from pgc.motion.amass import is_pose_npz

        skeleton_body = pose_body() if pose_body is not None and is_pose_npz(source.path) else None
        return clip_body_motion(source.path, body, source.clip, source.seconds, pose_body=skeleton_body)
    from pgc.synth.motions import make_motion

    return make_motion(body, source.spec, seconds=source.seconds)


def capture_body(capture_dir: Path | None, fitted_body_dir: Path | None, what: str, body: str = "truth"):
    """The skinned body in the capture pose that motions move, as :func:`motion_body` decides for ``body``: the
    capture's true body, else the body fitted to the capture (``fitted_body_dir/body.json``, re-based so that its
    fitted pose is the rest pose)."""
    if motion_body(capture_dir, body) == "truth":
        from pgc.synth.ground_truth import read_body_model

        return read_body_model(capture_dir)
    if fitted_body_dir is not None and (fitted_body_dir / "body.json").is_file():
        return fitted_body(fitted_body_dir)
    if body == "fit":
        raise PGCDataError(f"{what} moves on the body fitted to the capture, and the asset holds none "
                           f"({fitted_body_dir or 'ASSET/body_fit'}/body.json); reconstruct the asset again with "
                           "'pgc reconstruct CAPTURE --body fit'")
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
