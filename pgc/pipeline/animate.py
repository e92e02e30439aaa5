"""``pgc animate``: simulate an asset's garment on a body motion; the run folder holds the trajectories.

A motion is a built-in name (goalpost, spooky, arms-up, walk, arm-swing, posed by
:func:`pgc.synth.motions.make_motion`) or a captured clip (.amc with its ASF, .bvh, AMASS .npz: retargeted), both
on the body the asset moves on (:mod:`pgc.pipeline.motion_source`: the synthetic capture's true body, or the body
fitted to the capture), or a file (an .npz with ``vertices`` (T, V, 3) and ``faces``, or a folder of OBJ frames)
whose frame 0 is the capture pose.

Run folder: ``run.json`` (asset, capture, motion, ``motion_source``, ``body``: 'truth', 'fit' or null for a motion
file, fps, simulator, figures), ``garment.npz`` (vertices (T, V, 3)), ``body.npz`` (vertices, faces); cached by
content hash under ``stages/``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pgc.config import RunConfig
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.io.atomic import write_json
from pgc.io.body_fit import BODY_FIT_DIR
from pgc.io.limits import read_json
from pgc.io.timings import write_timings
from pgc.motion.drive import ClipOptions
from pgc.pipeline.cache import StageCache, array_key, asset_key
from pgc.pipeline.motion_source import (MotionSource, asset_body, capture_body, motion_body,
                                          resolve_motion)
from pgc.pipeline.runner import StageContext, StageRunner, Step
from pgc.pipeline.stage_io import save_npz
from pgc.stages import animate as animate_stage
from pgc.types import BodyMotion, GarmentAsset


@dataclass(frozen=True)
class AnimateInputs:
    asset: GarmentAsset
    motion: BodyMotion


def compute_animate(ctx: StageContext[AnimateInputs], folder: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """The garment's vertices per frame (T, V, 3), simulated by the configured simulator."""
    sim = ctx.cfg.create("simulator").simulate(ctx.inputs.asset.garment, ctx.inputs.motion, ctx.reporter)
    save_npz(folder / "garment.npz", vertices=sim.vertices)
    return sim.vertices, sim.figures


def load_animate(ctx: StageContext[AnimateInputs], folder: Path) -> np.ndarray:
    return np.load(folder / "garment.npz")["vertices"]


STAGES = ((animate_stage.STAGE, Step(compute_animate, load_animate)),)
"""The stages of ``pgc animate``, each with its code."""


def source_capture(asset_config: dict) -> Path | None:
    """The capture an asset was reconstructed from (recorded by ``pgc reconstruct``)."""
    src = asset_config.get("source", {}).get("capture")
    return Path(src) if src else None


def animate(asset_dir: str | Path, motion_spec: str, out: str | Path, cfg: RunConfig,
            capture_dir: str | Path | None = None, reporter: Reporter | None = None,
            clip: ClipOptions = ClipOptions()) -> Path:
    """Simulate the asset's garment on the motion (``clip``: how to read a captured clip); returns the run
    folder."""
    from pgc.io.asset import read_asset

    reporter = reporter or Reporter.silent()
    asset_dir, out = Path(asset_dir), Path(out)
    asset = read_asset(asset_dir)
    capture = Path(capture_dir) if capture_dir else source_capture(asset.config)
    source = MotionSource(motion_spec, cfg.stage("animate").seconds, clip)
    asked = asset_body(asset.config, capture)
    body = motion_body(capture, asked) if source.kind != "file" else None
    motion = resolve_motion(source, lambda what: capture_body(capture, asset_dir / BODY_FIT_DIR, what, asked),
                            lambda: cfg.create("body_model"))
    runner = StageRunner(StageCache(out / "stages"), StageContext(cfg, reporter, AnimateInputs(asset, motion)), {
        "asset": asset_key(asset_dir), "motion": {"spec": motion_spec, "vertices": array_key(motion.vertices),
                                                  "faces": array_key(motion.faces), "fps": motion.fps}})
    for stage, step in STAGES:
        runner.run(stage, step)
    save_npz(out / "garment.npz", vertices=runner.ctx.values["animate"], faces=asset.garment.faces)
    save_npz(out / "body.npz", vertices=motion.vertices, faces=motion.faces)
    figures, timings = runner.figures()
    figures, timings = figures["animate"], (timings or {}).get("animate")
    write_timings(out, timings or {})
    write_json(out / "run.json", {  # last: a run folder with a run.json is complete
        "asset": str(asset_dir.resolve()), "capture": None if capture is None else str(capture.resolve()),
        "motion": motion_spec, "motion_source": source.record(), "body": body, "fps": motion.fps,
        "frames": motion.num_frames,
        "simulator": cfg.roles["simulator"].name, "figures": figures})
    return out


def read_run(run_dir: str | Path) -> dict:
    run_dir = Path(run_dir)
    meta = run_dir / "run.json"
    if not meta.is_file():
        raise PGCDataError(f"{run_dir}: not a run folder (no run.json); make one with 'pgc animate'")
    return read_json(meta, "run.json")
