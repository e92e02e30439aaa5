"""The sweep's tasks and its work folders, laid out so that configurations share what they have in common.

``OUT/captures/<scene>-<key>/``: a synthetic scene (key: its spec and the configuration's scene renderer).
``OUT/assets/<scene>-<key>/``: one asset per scene and *reconstruct-affecting* configuration (key: the scene's
key and the resolved configuration without the downstream tables :data:`DOWNSTREAM`), so configurations that
differ only downstream share one asset. ``OUT/runs/<scene>-<motion>-<key>/``: one run folder per asset, motion and resolved configuration.
A folder that another configuration's folder could partly reuse starts as a copy of that folder's stage
caches (:func:`seed_from`): the asset of the scene's first configuration, or the run of the first
configuration with the same asset and motion. The pipeline's own content keys then decide which stages are
reused (e.g. mesh, splats and base colour when only the BRDF differs) and which are recomputed.
``OUT/results/<task>.json``: each finished task's result; a rerun reads them and runs only what is missing.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError
from pgc.io.limits import read_json
from pgc.pipeline.cache import content_key, file_key
from pgc.sweep.engine import Task
from pgc.sweep.spec import Configuration, Scene, Sweep

DOWNSTREAM = {"roles": ("simulator", "filter", "metric"), "stages": ("animate", "render", "eval")}
"""Configuration tables that do not change the asset (left out of the asset folder's key). A table missing
here only costs sharing, never correctness: the pipeline's stage keys still decide every reuse."""
SEEDED = ("stages", "render", "gt", "relit")
"""Cache folders copied from a donor folder (stage caches, ground-truth renders and the relit runs' own, all
content-keyed)."""
LOCK_COMMAND = "pgc sweep"


def asset_config_key(cfg: Any) -> str:
    resolved = cfg.to_dict()
    stages = {k: v for k, v in resolved.pop("stages", {}).items() if k not in DOWNSTREAM["stages"]}
    return content_key("asset-config", {k: v for k, v in resolved.items() if k not in DOWNSTREAM["roles"]}, stages)


def scene_key(scene: Scene, cfg: Any) -> str:
    """The key of a scene's capture: a synthetic scene's spec and the scene renderer of the configuration ``cfg``
    that renders it, or a capture folder's content."""
    if scene.synth is not None:
        return content_key("synth-scene", scene.synth, cfg.role_key("scene_renderer"))
    return content_key("capture-scene", file_key(scene.capture))


@dataclass
class Unit:
    """One (scene, configuration, motion) of the sweep with the tasks it needs (motion None: reconstruct only)."""

    scene: Scene
    configuration: Configuration
    motion: str | None
    capture: str
    asset_task: str
    run_task: str | None


def plan(sweep: Sweep, out: Path) -> tuple[list[Task], list[Unit], dict[str, Any]]:
    """The tasks still to run, every unit of the sweep, and the results of tasks finished by an earlier run."""
    tasks: dict[str, Task] = {}
    done: dict[str, Any] = {}
    units: list[Unit] = []

    def add(key: str, fn: Any, args: tuple, deps: list[str]) -> str:
        if key in tasks or key in done:
            return key
        cached = read_result(out, key)
        if cached is not None:
            done[key] = cached
            return key
        args = args + tuple(done[d] for d in deps if d in done)
        tasks[key] = Task(key, fn, args, tuple(d for d in deps if d not in done))
        return key

    root = sweep.path.parent
    motions = [str((root / m).resolve()) if (root / m).exists() else m for m in sweep.motions]
    for scene in sweep.scenes:
        first_asset: tuple[str, Path] | None = None
        first_run: dict[tuple[str, str], tuple[str, Path]] = {}
        for conf in sweep.configurations:
            skey = scene_key(scene, conf.cfg)  # configurations with one scene renderer share the capture
            if scene.synth is not None:
                capture = out / "captures" / f"{scene.name}-{skey}"
                cap_task = add(f"capture-{skey}", make_capture,
                               (scene.synth, str(capture), conf.data, conf.source, str(out)), [])
                cap_deps = [cap_task]
            else:
                capture, cap_deps = scene.capture, []
            akey = content_key("asset", skey, asset_config_key(conf.cfg))
            asset = out / "assets" / f"{scene.name}-{akey}"
            donor = first_asset if first_asset and first_asset[0] != f"asset-{akey}" else None
            asset_task = add(f"asset-{akey}", make_asset,
                             (str(capture), str(asset), conf.data, conf.source, str(donor[1]) if donor else None,
                              str(out)), cap_deps + ([donor[0]] if donor else []))
            first_asset = first_asset or (asset_task, asset)
            if "animate" not in sweep.steps:
                units.append(Unit(scene, conf, None, str(capture), asset_task, None))
                continue
            for motion_name, motion in zip(sweep.motions, motions):
                rkey = content_key("run", akey, motion, conf.cfg.to_dict(), sweep.steps, sweep.lights)
                run = out / "runs" / f"{scene.name}-{Path(motion_name).stem.replace(':', '-')}-{rkey}"
                rdonor = first_run.get((asset_task, motion))
                rdonor = rdonor if rdonor and rdonor[0] != f"run-{rkey}" else None
                run_task = add(f"run-{rkey}", make_run,
                               (str(asset), str(capture), motion, str(run), conf.data, conf.source, sweep.steps,
                                sweep.lights, str(rdonor[1]) if rdonor else None, str(out)),
                               [asset_task] + ([rdonor[0]] if rdonor else []))
                first_run.setdefault((asset_task, motion), (run_task, run))
                units.append(Unit(scene, conf, motion_name, str(capture), asset_task, run_task))
    return list(tasks.values()), units, done


def result_path(out: Path, key: str) -> Path:
    return Path(out) / "results" / f"{key}.json"


def read_result(out: Path, key: str) -> dict[str, Any] | None:
    path = result_path(out, key)
    if not path.is_file():
        return None
    try:
        return read_json(path, "sweep result")
    except PGCDataError:  # malformed or over the limits: the task runs again
        return None


def _finish(out: str, key: str, result: dict[str, Any]) -> dict[str, Any]:
    from pgc.io.atomic import write_json

    write_json(result_path(Path(out), key), result)
    return result


def seed_from(donor: str | None, folder: Path) -> bool:
    """Copy the donor folder's cache folders (:data:`SEEDED`) into a new ``folder``; False when ``folder``
    already exists (a resumed task keeps its own caches) or there is no donor."""
    if donor is None or folder.exists():
        return False
    folder.mkdir(parents=True)
    for name in SEEDED:
        if (Path(donor) / name).is_dir():
            shutil.copytree(Path(donor) / name, folder / name)
    return True


def make_capture(synth: dict[str, Any], folder: str, data: dict[str, Any], source: str, out: str,
                 *deps: Any) -> dict[str, Any]:
    """Generate the synthetic capture of a scene spec (``preset``, ``garment``, ``fabric``, ``seed``, ``framing``,
    and ``detail``, ``fit``, ``looseness`` where given; a missing or None value keeps the preset's) with the scene
    renderer of the configuration ``data``, as ``pgc synth --config`` does with the same options."""
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.render import scene_renderer

    start = time.perf_counter()
    cfg = _config(data, source)
    renderer = scene_renderer(cfg)
    preset = get_preset(synth["preset"], framing=synth.get("framing"))
    generate(folder, preset, garment=synth.get("garment"), fabric=synth.get("fabric"), seed=synth["seed"],
             looseness=synth.get("looseness"), detail=synth.get("detail"), fit=synth.get("fit"), renderer=renderer,
             body_model=cfg.create("body_model"))
    key = f"capture-{Path(folder).name.rsplit('-', 1)[1]}"
    return _finish(out, key, {"capture": folder, "seconds": time.perf_counter() - start})


def _config(data: dict[str, Any], source: str) -> Any:
    from pgc import config as config_mod

    return config_mod.resolve(data, None, source=source)


def make_asset(capture: str, folder: str, data: dict[str, Any], source: str, donor: str | None, out: str,
               *deps: Any) -> dict[str, Any]:
    """Reconstruct the asset of one scene and configuration (stage caches seeded from ``donor``)."""
    from pgc.io.lock import FolderLock
    from pgc.pipeline.reconstruct import reconstruct

    cfg = _config(data, source)
    start = time.perf_counter()
    seeded = seed_from(donor, Path(folder))
    with FolderLock(folder, LOCK_COMMAND):
        asset = reconstruct(capture, folder, cfg)
    material = asset.figures.get("material", {})
    result = {"asset": folder, "brdf": asset.material.brdf, "seeded": seeded, "seconds": time.perf_counter() - start,
              "stage_seconds": asset.figures.get("seconds", {}),
              "figures": {k: v for k, v in material.items() if isinstance(v, (int, float)) and not isinstance(v, bool)},
              "gaussians": asset.figures.get("gaussians_garment")}
    return _finish(out, f"asset-{Path(folder).name.rsplit('-', 1)[1]}", result)


def make_run(asset: str, capture: str, motion: str, folder: str, data: dict[str, Any], source: str,
             steps: list[str], lights: list[str], donor: str | None, out: str, *deps: Any) -> dict[str, Any]:
    """Animate one asset on one motion, then render and evaluate it as ``steps`` say, under each of ``lights``
    (:data:`pgc.pipeline.relight.EVAL_LIGHTS`; novel lights in the run's relit runs, their environment maps in
    ``OUT/lights/``). ``metrics``: light -> variant -> metric."""
    from pgc.io.lock import FolderLock
    from pgc.pipeline.animate import animate
    from pgc.pipeline.evaluate import VARIANTS
    from pgc.pipeline.relight import EVAL_LIGHTS, render_and_evaluate

    cfg = _config(data, source)
    seconds: dict[str, float] = {}
    seeded = seed_from(donor, Path(folder))
    metrics: dict[str, dict[str, dict[str, float]]] = {}
    with FolderLock(folder, LOCK_COMMAND):
        start = time.perf_counter()
        animate(asset, motion, folder, cfg, capture)
        seconds["animate"] = time.perf_counter() - start
        for name in lights if "render" in steps else ():
            ev = render_and_evaluate(Path(folder), Path(capture) if "eval" in steps else None, cfg, EVAL_LIGHTS[name],
                                     Path(out) / "lights", timings=seconds)
            if ev is not None:
                metrics[name] = {v: {k: x for k, x in ev[v].items() if k != "per_frame"} for v in VARIANTS}
    result = {"run": folder, "seeded": seeded, "seconds": seconds, "metrics": metrics}
    return _finish(out, f"run-{Path(folder).name.rsplit('-', 1)[1]}", result)
