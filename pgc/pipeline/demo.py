"""``pgc demo``: the whole pipeline on a synthetic scene, measured against its ground truth.

synthetic capture -> reconstruct -> animate on the paper's three test motions (goalpost, spooky, arms-up) and
a shipped CMU clip (:data:`DEMO_CLIP`, in place) -> hybrid render -> ground-truth renders of the same simulated geometry
-> metrics -> report, under the capture light and, on :data:`RELIT_MOTIONS`, under novel lights
(:mod:`pgc.pipeline.relight`: the motion's relit runs, ``runs/MOTION/relit/LIGHT/``, with their own truth).
Every step is cached, so a rerun after an interruption resumes; ``metrics.json`` and ``report.html`` land in OUT.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import Any

from pgc import config as config_mod
from pgc.errors import PGCConfigError
from pgc.events import Reporter
from pgc.io.atomic import write_json

PAPER_MOTIONS = ("goalpost", "spooky", "arms-up")
DEMO_CLIP = "cmu:02_01"
"""The captured clip the demo adds to the paper's motions: CMU subject 2's walk, retargeted onto the body."""
DEMO_MOTIONS = PAPER_MOTIONS + (DEMO_CLIP,)
RELIT_MOTIONS = ("spooky",)
"""The motions the demo also evaluates under the novel lights (one keeps the default demo within its budget: each
light on all three motions would add about 3 minutes; docs/pipeline.md, "Novel lights")."""


def demo_config(preset: str, user_config: str | Path | None = None, registry=None) -> config_mod.RunConfig:
    """The preset's settings (``pgc/presets/demo_<preset>.toml``; a scene preset without its own file takes
    ``demo_default.toml``) under the user's config file, validated."""
    presets = resources.files("pgc") / "presets"
    preset_file = presets / f"demo_{preset}.toml"
    if not preset_file.is_file():
        preset_file = presets / "demo_default.toml"
    data = config_mod.load_toml(str(preset_file))
    if user_config is not None:
        data = config_mod.deep_merge(data, config_mod.load_toml(user_config))
    return config_mod.resolve(data, registry, source=str(user_config or preset_file))


def synthetic_capture(folder: Path, preset: str, seed: int, cfg: config_mod.RunConfig,
                      reporter: Reporter | None = None) -> bool:
    """The synthetic capture of ``preset`` and ``seed`` in ``folder``, made by ``cfg``'s scene renderer and body
    model: generated, or copied from the capture cache (:mod:`pgc.pipeline.capture_cache`), unless the folder
    already holds it. Returns whether the folder was (re)filled."""
    from pgc.pipeline.capture_cache import cached_capture, generator_classes
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.render import scene_renderer

    def make(path: Path) -> None:
        generate(path, preset=preset, seed=seed, reporter=reporter, renderer=scene_renderer(cfg),
                 body_model=cfg.create("body_model"))

    parts = ("demo", asdict(get_preset(preset)), seed, cfg.role_key("scene_renderer"), cfg.role_key("body_model"))
    return cached_capture(folder, parts, make, *generator_classes(cfg))


def run_demo(out: str | Path, preset: str = "default", user_config: str | Path | None = None,
             motions: tuple[str, ...] = DEMO_MOTIONS, seed: int = 0, reporter: Reporter | None = None,
             registry=None, lights: tuple[str, ...] | None = None,
             relit_motions: tuple[str, ...] = RELIT_MOTIONS) -> dict[str, Any]:
    """The demo into ``out``; returns the summary written to ``out/metrics.json``: the capture light's means per
    variant over ``motions`` (top level, and per motion under ``motions``) and, under ``lights``, each evaluated
    light's means over ``relit_motions`` (the capture light's too, so that they compare like with like).
    ``lights``: names of :data:`pgc.pipeline.relight.EVAL_LIGHTS` (default all; the capture light always)."""
    from pgc.io.timings import read_timings
    from pgc.motion.drive import EVALUATED_CLIP
    from pgc.pipeline.animate import animate
    from pgc.pipeline.reconstruct import reconstruct
    from pgc.pipeline.relight import EVAL_LIGHTS, check_light_names, render_and_evaluate
    from pgc.pipeline.render import choose_kernel
    from pgc.pipeline.report import write_report

    reporter = reporter or Reporter.silent()
    out = Path(out)
    names = check_light_names(list(lights or EVAL_LIGHTS), "pgc demo --lights")
    if "capture" not in names:
        names.insert(0, "capture")  # the relit results are read against it
    if not relit_motions or not set(relit_motions) <= set(motions):
        raise PGCConfigError(f"relit motions {list(relit_motions)}: give one or more of the demo's motions "
                             f"{list(motions)}")
    cfg = demo_config(preset, user_config, registry)
    cfg.check_implementations()
    timings: dict[str, float] = {}

    def timed(name: str, fn):
        start = time.perf_counter()
        value = fn()
        timings[name] = timings.get(name, 0.0) + time.perf_counter() - start
        return value

    capture = out / "capture"
    start = time.perf_counter()
    if synthetic_capture(capture, preset, seed, cfg, reporter):
        timings["synth"] = time.perf_counter() - start
    timed("reconstruct", lambda: reconstruct(capture, out / "asset", cfg, reporter))
    results: dict[str, dict[str, Any]] = {name: {} for name in names}  # light -> motion -> eval result
    decisions: list = []

    def decide_once(renderer, capture_views):
        """The kernel rule depends on the asset, the capture and the config only: one decision serves every
        motion and light (taken when the first render stage is computed)."""
        if not decisions:
            decisions.append(choose_kernel(renderer, capture_views, cfg))
        return decisions[0]

    for motion in motions:
        run = out / "runs" / motion
        timed("animate", lambda: animate(out / "asset", motion, run, cfg, capture, reporter, EVALUATED_CLIP))
        for name in names if motion in relit_motions else ("capture",):
            results[name][motion] = render_and_evaluate(run, capture, cfg, EVAL_LIGHTS[name], out / "lights",
                                                        reporter, decide_once, timings)
    summary = summarise(results["capture"])
    summary["lights"] = {}
    for name, res in results.items():
        res = {m: r for m, r in res.items() if m in relit_motions}
        summary["lights"][name] = {"description": EVAL_LIGHTS[name].description,
                                   "light": next(iter(res.values()))["light"], **summarise(res)}
    summary.update(preset=preset, seconds=timings, stages=read_timings(out / "asset").get("seconds", {}),
                   config=cfg.to_dict())
    write_json(out / "metrics.json", summary)
    write_report(out, summary, results["capture"])
    return summary


def summarise(results: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Mean of every metric over motions (each motion's value is already a mean over frames and views)."""
    from pgc.pipeline.evaluate import VARIANTS

    summary: dict[str, Any] = {"motions": {}}
    for variant in VARIANTS:
        names = [k for k in next(iter(results.values()))[variant] if k != "per_frame"]
        summary[variant] = {n: sum(r[variant][n] for r in results.values()) / len(results) for n in names}
    for motion, r in results.items():
        summary["motions"][motion] = {v: {k: x for k, x in r[v].items() if k != "per_frame"} for v in VARIANTS}
    return summary
