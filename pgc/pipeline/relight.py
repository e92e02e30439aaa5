"""The lights ``pgc demo`` and ``pgc sweep`` evaluate under: the capture light and two novel lights.

A novel light is an environment map (:func:`pgc.synth.rig.relight_envmap`) written once into a lights folder
(``OUT/lights/<kind>.exr``) and turned by a fixed angle. Each is evaluated in a *relit run*,
``RUN/relit/<name>/``: a run folder that shares the run's simulation (``run.json``, ``garment.npz``,
``body.npz``; hard links where the file system allows) and holds its own frames rendered under the light, its
ground truth rendered under the same light and its ``metrics.json``: what ``pgc render RELIT --light FILE
--light-rotation DEG`` and ``pgc eval RELIT --gt CAPTURE`` write. Frames and truth are cached by content (the
render stage's key holds the light file's hash and angle; the truth's cache key holds the light's identity),
so a rerun renders nothing again.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

from pgc.config import RunConfig
from pgc.errors import PGCConfigError
from pgc.events import Reporter


@dataclass(frozen=True)
class EvalLight:
    """A light the demo and the sweeps evaluate under: ``envmap`` is the environment map kind of
    :func:`pgc.synth.rig.relight_envmap` (None: the capture light), turned ``rotation_deg`` about +Y."""

    name: str
    envmap: str | None
    rotation_deg: float
    description: str


EVAL_LIGHTS = {light.name: light for light in (
    EvalLight("capture", None, 0.0, "the capture light (the dome's uniform environment)"),
    EvalLight("sky-rot90", "sky", 90.0, "a sky (small warm sun, blue zenith, dark ground) turned 90 deg about +Y"),
    EvalLight("low-key", "low-key", 0.0, "a low key light: one hard key low at the side over a faint fill"),
)}
"""Name -> light, in the order tables list them."""
ENVMAP_HEIGHT = 64
"""Rows of the novel lights' environment maps (2 x as many columns): about 2.8 degrees a pixel."""
RELIT_FOLDER = "relit"
SHARED_RUN_FILES = ("run.json", "garment.npz", "body.npz")
"""The files of a run that its relit runs share."""


def check_light_names(names: list[str], where: str) -> list[str]:
    """``names`` once each is a light of :data:`EVAL_LIGHTS` and none repeats, else a config error at ``where``."""
    if not names:
        raise PGCConfigError(f"{where}: give at least one light of {', '.join(EVAL_LIGHTS)}")
    for name in names:
        if name not in EVAL_LIGHTS:
            raise PGCConfigError(f"{where}: unknown light '{name}'; lights: {', '.join(EVAL_LIGHTS)}")
    if len(set(names)) != len(names):
        raise PGCConfigError(f"{where}: a light is named twice in {names}")
    return list(names)


def light_file(folder: Path, light: EvalLight) -> Path:
    """The environment map file of the novel ``light`` in ``folder`` (``<kind>.exr``), written when it is missing
    or holds another map (written atomically: workers of a sweep may race)."""
    import numpy as np

    from pgc.io.images import read_envmap, write_exr
    from pgc.synth.rig import relight_envmap

    if light.envmap is None:
        raise ValueError(f"light '{light.name}' is the capture light: it has no environment map file")
    path = Path(folder) / f"{light.envmap}.exr"
    env = relight_envmap(ENVMAP_HEIGHT, light.envmap)
    if not (path.is_file() and np.array_equal(read_envmap(path), env)):
        path.parent.mkdir(parents=True, exist_ok=True)
        write_exr(path, env)
    return path


def relit_run(run_dir: Path, name: str) -> Path:
    """``RUN/relit/<name>/``, a run folder sharing the run's :data:`SHARED_RUN_FILES` (replaced when the run's
    changed, e.g. after it was animated again)."""
    from pgc.pipeline.cache import file_key

    folder = Path(run_dir) / RELIT_FOLDER / name
    folder.mkdir(parents=True, exist_ok=True)
    for file in SHARED_RUN_FILES:
        src, dst = Path(run_dir) / file, folder / file
        if dst.is_file() and file_key(dst) == file_key(src):
            continue
        tmp = folder / f".{file}.{os.getpid()}.tmp"
        tmp.unlink(missing_ok=True)
        try:
            os.link(src, tmp)
        except OSError:  # no hard links here (another file system, Windows FAT): a copy
            import shutil

            shutil.copyfile(src, tmp)
        os.replace(tmp, dst)
    return folder


def render_and_evaluate(run_dir: Path, capture: Path | None, cfg: RunConfig, light: EvalLight, lights_folder: Path,
                        reporter: Reporter | None = None, decide: Callable | None = None,
                        timings: dict[str, float] | None = None) -> dict[str, Any] | None:
    """Render the animated run under ``light`` (the capture light: in the run itself; a novel light: in its
    relit run, with the environment map of ``lights_folder``) and, unless ``capture`` is None, evaluate it
    against the capture's ground truth under the same light; returns the eval result (``metrics.json``) or
    None. ``decide``: the kernel decision shared by every render of one asset
    (:func:`pgc.pipeline.render.render_run`). ``timings``: seconds are added under 'render' and 'eval' (capture
    light) or 'relit_render' and 'relit_eval' (novel lights)."""
    import time

    from pgc.pipeline.evaluate import evaluate_run
    from pgc.pipeline.render import envmap_light, render_run

    timings = {} if timings is None else timings
    prefix = "" if light.envmap is None else "relit_"

    def add(step: str, since: float) -> None:
        timings[prefix + step] = timings.get(prefix + step, 0.0) + time.perf_counter() - since

    start = time.perf_counter()
    if light.envmap is None:
        folder, lit, file = Path(run_dir), None, None
    else:
        folder = relit_run(run_dir, light.name)
        file = light_file(lights_folder, light)
        lit = replace(envmap_light(folder, file), rotation_deg=light.rotation_deg)
    render_run(folder, cfg, lit, reporter, decide=decide, light_file=file)
    add("render", start)
    if capture is None:
        return None
    start = time.perf_counter()
    result = evaluate_run(folder, capture, cfg, reporter)
    add("eval", start)
    return result


def light_folders(run_dir: Path) -> dict[str, Path]:
    """Light name -> the run folder rendered under it: the run itself for 'capture', then its relit runs that
    hold rendered frames, in :data:`EVAL_LIGHTS` order."""
    found = {"capture": Path(run_dir)}
    for name in EVAL_LIGHTS:
        folder = Path(run_dir) / RELIT_FOLDER / name
        if name != "capture" and (folder / "render" / "render.json").is_file():
            found[name] = folder
    return found
