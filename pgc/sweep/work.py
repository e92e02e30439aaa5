"""The sweep's tasks and its work folders, laid out so that configurations share what they have in common.

``OUT/captures/<scene>-<key>/``: a synthetic scene (key: its spec and the configuration's scene renderer).
``OUT/assets/<scene>-<key>/``: one asset per scene and *reconstruct-affecting* configuration (key: the scene's
key and the resolved configuration without the downstream tables :data:`DOWNSTREAM`), so configurations that
differ only downstream share one asset. ``OUT/runs/<scene>-<motion>-<key>/``: one run folder per asset, motion and
resolved configuration.
A folder that another configuration's folder could partly reuse starts as a copy of that folder's stage
caches (:func:`seed_from`): the asset of the scene's first configuration, or a run folder of the same asset and
motion that an earlier version of the sweep left (:func:`earlier_run`: a changed metric or eval setting then
recomputes no simulation), else the scene's first run on the same motion. The pipeline's own content keys then
decide which stages are reused (e.g. mesh, splats and base colour when only the BRDF differs; the ground-truth
renders when the simulation came out the same) and which are recomputed.
``OUT/results/<task>.json``: each finished task's result; a rerun reads them and runs only what is missing (a task
whose result is on record but whose folder is not, as after a scene was renamed, runs again, its new folder seeded
from the folder it recorded: :func:`recorded_folder`).

With ``holdout_every`` k, each scene's capture is split into ``OUT/captures/<scene>-<key>-train<k>/`` (the views
that reconstruct) and ``-heldout<k>/`` (every k-th view: the cameras the runs are rendered and evaluated from),
both holding the capture's ground truth. An evaluation mode other than 'appearance' (which every run task
evaluates) is a task of its own per run, ``eval-<mode>-<run key>``, evaluating the run under each light.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass, field
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


def priority(motion_index: int, motions: int, mode_task: bool = False) -> int:
    """A run's task priority: breadth first, every scene's run on the first motion before any on the second;
    the mode tasks after every run (the independent truth simulation is the costly part). A sweep stopped early
    then has its scenes and seeds covered on the first motions, with their appearance metrics."""
    return -motion_index - (motions if mode_task else 0)


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
    mode_tasks: dict[str, str] = field(default_factory=dict)
    """Evaluation mode -> the task whose result holds its metrics (``appearance``: the run task)."""


def plan(sweep: Sweep, out: Path, need_folders: bool = True) -> tuple[list[Task], list[Unit], dict[str, Any]]:
    """The tasks still to run, every unit of the sweep, and the results of tasks finished by an earlier run
    (with ``need_folders``, only those whose folders are still there: the later tasks read them)."""
    tasks: dict[str, Task] = {}
    done: dict[str, Any] = {}
    units: list[Unit] = []

    def add(key: str, fn: Any, args: tuple, deps: list[str], priority: int = 0, outputs: tuple[Path, ...] = ()) -> str:
        """Plan task ``key`` unless it is planned or finished: a result on record (whose ``outputs``, the folders
        it wrote, named by this sweep's scenes, still exist, with ``need_folders``)."""
        if key in tasks or key in done:
            return key
        cached = read_result(out, key)
        if cached is not None and (not need_folders or all(Path(o).is_dir() for o in outputs)):
            done[key] = cached
            return key
        args = args + tuple(done[d] for d in deps if d in done)
        tasks[key] = Task(key, fn, args, tuple(d for d in deps if d not in done), priority)
        return key

    finished = finished_runs(out)
    root = sweep.path.parent
    motions = [str((root / m).resolve()) if (root / m).exists() else m for m in sweep.motions]
    for scene in sweep.scenes:
        first_asset: tuple[str, Path] | None = None
        first_run: dict[str, tuple[str, Path]] = {}  # motion -> the scene's first run on it
        for conf in sweep.configurations:
            skey = scene_key(scene, conf.cfg)  # configurations with one scene renderer share the capture
            if scene.synth is not None:
                capture = out / "captures" / f"{scene.name}-{skey}"
                cap_task = add(f"capture-{skey}", make_capture,
                               (scene.synth, str(capture), conf.data, conf.source, str(out)), [], outputs=(capture,))
                cap_deps = [cap_task]
            else:
                capture, cap_deps = scene.capture, []
            eval_capture = capture
            if sweep.holdout_every:
                k = sweep.holdout_every
                train = out / "captures" / f"{scene.name}-{skey}-train{k}"
                eval_capture = out / "captures" / f"{scene.name}-{skey}-heldout{k}"
                split_key = f"split-{skey}-{k}"
                cap_deps = [add(split_key, make_split, (str(capture), str(train), str(eval_capture), k, split_key,
                                                        str(out)), cap_deps, outputs=(train, eval_capture))]
                capture = train
            akey = content_key("asset", skey, asset_config_key(conf.cfg),
                               *((f"train{sweep.holdout_every}",) if sweep.holdout_every else ()))
            asset = out / "assets" / f"{scene.name}-{akey}"
            donor = first_asset if first_asset and first_asset[0] != f"asset-{akey}" else None
            renamed = recorded_folder(out, f"asset-{akey}", "asset", asset)
            asset_donor = str(renamed or donor[1]) if renamed or donor else None
            asset_task = add(f"asset-{akey}", make_asset,
                             (str(capture), str(asset), conf.data, conf.source, asset_donor, str(out)),
                             cap_deps + ([donor[0]] if donor and not renamed else []), outputs=(asset,))
            first_asset = first_asset or (asset_task, asset)
            if "animate" not in sweep.steps:
                units.append(Unit(scene, conf, None, str(capture), asset_task, None))
                continue
            for i, (motion_name, motion) in enumerate(zip(sweep.motions, motions)):
                rkey = content_key("run", akey, motion, conf.cfg.to_dict(), sweep.steps, sweep.lights)
                run = out / "runs" / f"{scene.name}-{Path(motion_name).stem.replace(':', '-')}-{rkey}"
                rdonor = first_run.get(motion)
                rdonor = rdonor if rdonor and rdonor[0] != f"run-{rkey}" else None
                earlier = recorded_folder(out, f"run-{rkey}", "run", run) or earlier_run(run, asset, motion, finished,
                                                                                         conf.name)
                donor_folder = earlier or (rdonor[1] if rdonor else None)
                run_task = add(f"run-{rkey}", make_run,
                               (str(asset), str(eval_capture), motion, str(run), conf.data, conf.source, sweep.steps,
                                sweep.lights, str(donor_folder) if donor_folder else None, str(out), conf.name),
                               [asset_task] + ([rdonor[0]] if rdonor and not earlier else []),
                               priority(i, len(motions)), (run,))
                first_run.setdefault(motion, (run_task, run))
                modes = {m: run_task if m == "appearance" else
                         add(f"eval-{m}-{rkey}", make_mode_eval, (str(run), str(eval_capture), conf.data, conf.source,
                                                                  sweep.lights, m, str(out)), [run_task],
                             priority(i, len(motions), mode_task=True), (run,))
                         for m in (sweep.modes if "eval" in sweep.steps else ())}
                units.append(Unit(scene, conf, motion_name, str(eval_capture), asset_task, run_task, modes))
    return list(tasks.values()), units, done


def finished_runs(out: Path) -> dict[str, str | None]:
    """Run folder name -> the configuration whose run task finished it (None where the result does not say),
    from ``OUT/results``."""
    names: dict[str, str | None] = {}
    for path in sorted((Path(out) / "results").glob("run-*.json")):
        result = read_result(out, path.stem)
        if result and isinstance(result.get("run"), str):
            configuration = result.get("configuration")
            names[Path(result["run"]).name] = configuration if isinstance(configuration, str) else None
    return names


def earlier_run(run: Path, asset: Path, motion: str, finished: dict[str, str | None],
                configuration: str) -> Path | None:
    """A finished run folder (one of ``finished``, :func:`finished_runs`) that an earlier version of the sweep left
    for the same asset and motion (same scene and motion name, another key: a downstream setting such as the
    metrics or the eval's changed), whose stage caches seed ``run``: the same configuration's if any, else the
    first; None when ``run`` exists or there is none. Only finished folders: no task of this sweep writes them."""
    if run.exists() or not run.parent.is_dir():
        return None
    prefix = run.name.rsplit("-", 1)[0] + "-"
    found = []
    for folder in sorted(run.parent.glob(f"{prefix}*")):
        if folder.name not in finished or folder.name.rsplit("-", 1)[0] + "-" != prefix \
                or not (folder / "run.json").is_file():
            continue
        try:
            meta = read_json(folder / "run.json", "run metadata")
        except PGCDataError:
            continue
        if isinstance(meta.get("asset"), str) and Path(meta["asset"]).resolve() == asset.resolve() \
                and meta.get("motion") == motion:
            found.append(folder)
    return next((f for f in found if finished[f.name] == configuration), found[0] if found else None)


def recorded_folder(out: Path, key: str, field: str, folder: Path) -> Path | None:
    """The folder that task ``key`` wrote when it finished (its result's ``field``) if it is still there and is not
    ``folder``: the same work under another name (the scene was renamed in the sweep file), whose stage caches
    seed ``folder``. No task of the sweep writes it: the task of ``key`` now writes ``folder``."""
    result = read_result(out, key)
    recorded = result.get(field) if result else None
    if not isinstance(recorded, str) or folder.exists() or Path(recorded).resolve() == folder.resolve():
        return None
    return Path(recorded) if Path(recorded).is_dir() else None


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
    and ``detail``, ``fit``, ``looseness``, ``views``, ``capture_light`` where given; a missing or None value keeps
    the preset's) with the scene renderer of the configuration ``data``, as ``pgc synth --config`` does with the
    same options."""
    from dataclasses import asdict

    from pgc.pipeline.capture_cache import cached_capture, generator_classes
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.render import scene_renderer

    start = time.perf_counter()
    cfg = _config(data, source)
    preset = get_preset(synth["preset"], framing=synth.get("framing"), views=synth.get("views"))
    overrides = {k: synth.get(k) for k in ("garment", "fabric", "looseness", "detail", "fit")}
    if synth.get("capture_light") is not None:  # only when given: the cache keys of other scenes stay as they were
        overrides["capture_light"] = synth["capture_light"]

    def make(path: Path) -> None:
        generate(path, preset, seed=synth["seed"], renderer=scene_renderer(cfg), body_model=cfg.create("body_model"),
                 **overrides)

    parts = ("sweep", asdict(preset), overrides, synth["seed"], cfg.role_key("scene_renderer"),
             cfg.role_key("body_model"))
    cached_capture(folder, parts, make, *generator_classes(cfg))
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


def make_split(capture: str, train: str, heldout: str, every: int, key: str, out: str, *deps: Any) -> dict[str, Any]:
    """Split ``capture`` into the view subsets ``train`` and ``heldout`` (every ``every``-th view, from view
    ``every - 1``): each a capture folder of hard links (copies where links fail) to the capture's files, its
    ``transforms.json`` listing its own views, and every file that belongs to no view (the ground truth)."""
    from pgc.splats.fitplan import heldout_split

    start = time.perf_counter()
    doc = read_json(Path(capture) / "transforms.json", "transforms.json")
    frames = doc.get("frames") if isinstance(doc, dict) else None
    if not isinstance(frames, list):
        raise PGCDataError(f"{capture}/transforms.json: no list 'frames'; generate the capture again")
    train_ids, held_ids = heldout_split(len(frames), every)
    if not held_ids:
        raise PGCDataError(f"{capture}: {len(frames)} views are too few to hold out every {every}th view (need "
                           f"{2 * every}); lower [sweep].holdout_every")
    view_files = [set(_paths_in(f)) for f in frames]
    for folder, ids in ((train, train_ids), (heldout, held_ids)):
        dropped = set().union(*(view_files[i] for i in range(len(frames)) if i not in ids))
        _link_capture(Path(capture), Path(folder), dropped, doc | {"frames": [frames[i] for i in ids]})
    return _finish(out, key, {"train": train, "heldout": heldout, "views_train": len(train_ids),
                              "views_heldout": len(held_ids), "seconds": time.perf_counter() - start})


def _paths_in(value: Any) -> list[str]:
    """Every string inside a transforms.json frame (its files' relative paths, and its name)."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [p for v in value.values() for p in _paths_in(v)]
    if isinstance(value, list):
        return [p for v in value for p in _paths_in(v)]
    return []


def _link_capture(src: Path, dst: Path, dropped: set[str], doc: dict[str, Any]) -> None:
    """``dst``: ``src``'s files except ``dropped`` (relative paths) and transforms.json, linked, then ``doc`` as its
    transforms.json (written last, so that a reader never sees a half-made capture)."""
    import os

    from pgc.io.atomic import write_json

    if dst.exists():  # an interrupted split: made again
        shutil.rmtree(dst)
    for path in sorted(p for p in src.rglob("*") if p.is_file()):
        rel = path.relative_to(src)
        if rel.as_posix() in dropped or rel.as_posix() == "transforms.json":
            continue
        (dst / rel).parent.mkdir(parents=True, exist_ok=True)
        try:
            os.link(path, dst / rel)
        except OSError:  # another file system: a copy
            shutil.copy2(path, dst / rel)
    write_json(dst / "transforms.json", doc)


def make_run(asset: str, capture: str, motion: str, folder: str, data: dict[str, Any], source: str,
             steps: list[str], lights: list[str], donor: str | None, out: str, configuration: str,
             *deps: Any) -> dict[str, Any]:
    """Animate one asset on one motion, then render and evaluate it as ``steps`` say, under each of ``lights``
    (:data:`pgc.pipeline.relight.EVAL_LIGHTS`; novel lights in the run's relit runs, their environment maps in
    ``OUT/lights/``). ``metrics``: light -> variant -> metric; ``configuration``: the sweep's name for ``data``."""
    from pgc.io.lock import FolderLock
    from pgc.motion.drive import EVALUATED_CLIP
    from pgc.pipeline.animate import animate
    from pgc.pipeline.evaluate import VARIANTS
    from pgc.pipeline.relight import EVAL_LIGHTS, render_and_evaluate

    cfg = _config(data, source)
    seconds: dict[str, float] = {}
    seeded = seed_from(donor, Path(folder))
    metrics: dict[str, dict[str, dict[str, float]]] = {}
    with FolderLock(folder, LOCK_COMMAND):
        start = time.perf_counter()
        animate(asset, motion, folder, cfg, capture, clip=EVALUATED_CLIP)
        seconds["animate"] = time.perf_counter() - start
        for name in lights if "render" in steps else ():
            ev = render_and_evaluate(Path(folder), Path(capture) if "eval" in steps else None, cfg, EVAL_LIGHTS[name],
                                     Path(out) / "lights", timings=seconds)
            if ev is not None:
                metrics[name] = {v: {k: x for k, x in ev[v].items() if k != "per_frame"} for v in VARIANTS}
    result = {"run": folder, "configuration": configuration, "seeded": seeded, "seconds": seconds, "metrics": metrics}
    return _finish(out, f"run-{Path(folder).name.rsplit('-', 1)[1]}", result)


TRUTH_SIM_CACHE = ("gt", "truth_sim")
"""Where a run folder caches its independent truth simulation (:func:`pgc.pipeline.independent.truth_simulation`):
a relit run shares the run's simulation and body, so it is given the run's cache files before it is evaluated
(the cache's own key still decides whether they are used)."""


def make_mode_eval(run: str, capture: str, data: dict[str, Any], source: str, lights: list[str], mode: str, out: str,
                   *deps: Any) -> dict[str, Any]:
    """Evaluate the rendered run ``run`` in evaluation ``mode`` under each of ``lights`` (the run itself for the
    capture light, its relit runs for the others), after the run task; ``metrics``: light -> variant -> metric."""
    import os

    from pgc.io.lock import FolderLock
    from pgc.pipeline.evaluate import VARIANTS, evaluate_run
    from pgc.pipeline.relight import RELIT_FOLDER

    cfg = _config(data, source)
    seconds: dict[str, float] = {}
    metrics: dict[str, dict[str, dict[str, float]]] = {}
    cache = Path(run).joinpath(*TRUTH_SIM_CACHE)
    with FolderLock(run, LOCK_COMMAND):
        for name in lights:
            folder = Path(run) if name == "capture" else Path(run) / RELIT_FOLDER / name
            if folder != Path(run) and cache.is_dir():
                target = folder.joinpath(*TRUTH_SIM_CACHE)
                target.mkdir(parents=True, exist_ok=True)
                for file in cache.iterdir():
                    if not (target / file.name).exists():
                        os.link(file, target / file.name)
            start = time.perf_counter()
            ev = evaluate_run(folder, capture, cfg, mode=mode)
            seconds[f"eval_{mode}"] = seconds.get(f"eval_{mode}", 0.0) + time.perf_counter() - start
            metrics[name] = {v: {k: x for k, x in ev[v].items() if k != "per_frame"} for v in VARIANTS}
            if not cache.is_dir() and folder.joinpath(*TRUTH_SIM_CACHE).is_dir():
                cache = folder.joinpath(*TRUTH_SIM_CACHE)  # the first light computed it
    result = {"run": run, "mode": mode, "seconds": seconds, "metrics": metrics}
    return _finish(out, f"eval-{mode}-{Path(run).name.rsplit('-', 1)[1]}", result)
