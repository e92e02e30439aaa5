"""``pgc animate``: simulate an asset's garment on a body motion; the run folder holds the trajectories.

A motion is a built-in name (goalpost, spooky, arms-up, walk, arm-swing: the body model stored with a
synthetic capture, posed by :func:`pgc.synth.motions.make_motion`), a captured clip (.amc with its ASF, or
.bvh: retargeted onto that body, :mod:`pgc.pipeline.motion_source`) or a file (an .npz with ``vertices`` (T, V, 3) and
``faces``, or a folder of OBJ frames) whose frame 0 is the capture pose.

Run folder: ``run.json`` (asset, motion, fps, simulator, figures), ``garment.npz`` (vertices (T, V, 3)),
``body.npz`` (vertices, faces); cached by content hash under ``stages/``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pgc.config import RunConfig
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.io.atomic import write_json
from pgc.io.limits import read_json
from pgc.io.timings import split_timings, write_timings
from pgc.motion.drive import ClipOptions
from pgc.pipeline.motion_source import resolve_motion
from pgc.pipeline.cache import StageCache, array_key, asset_key, content_key
from pgc.pipeline.stage_io import save_npz


CODE_VERSION = "2"
"""Version of the code computing the animate stage (part of its cache key)."""


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
    settings = cfg.stage("animate")
    motion = resolve_motion(motion_spec, capture, settings.seconds, clip)
    key = content_key("animate", asset_key(asset_dir), motion_spec, settings,
                      cfg.role_key("simulator"), array_key(motion.vertices), array_key(motion.faces), motion.fps)

    def compute(folder: Path):
        sim = cfg.create("simulator").simulate(asset.garment, motion, reporter)
        save_npz(folder / "garment.npz", vertices=sim.vertices)
        return sim.vertices, sim.figures

    result = StageCache(out / "stages").run("animate", key, compute,
                                            lambda f: np.load(f / "garment.npz")["vertices"], CODE_VERSION)
    save_npz(out / "garment.npz", vertices=result.value, faces=asset.garment.faces)
    save_npz(out / "body.npz", vertices=motion.vertices, faces=motion.faces)
    figures, timings = split_timings(StageCache(out / "stages").figures("animate"))
    write_timings(out, timings or {})
    write_json(out / "run.json", {  # last: a run folder with a run.json is complete
        "asset": str(asset_dir.resolve()), "capture": None if capture is None else str(capture.resolve()),
        "motion": motion_spec, "fps": motion.fps, "frames": motion.num_frames,
        "simulator": cfg.roles["simulator"].name, "figures": figures})
    return out


def read_run(run_dir: str | Path) -> dict:
    run_dir = Path(run_dir)
    meta = run_dir / "run.json"
    if not meta.is_file():
        raise PGCDataError(f"{run_dir}: not a run folder (no run.json); make one with 'pgc animate'")
    return read_json(meta, "run.json")
