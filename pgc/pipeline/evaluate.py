"""``pgc eval``: metrics of a rendered run against ground truth, for the hybrid and both ablations.

Ground truth: for a synthetic capture, the run's own frames are rendered with the ground-truth materials. Mode
``appearance`` (default): on matching geometry, the ground-truth garment tied to the reconstructed rest garment
(:mod:`pgc.pipeline.transfer`) and carried along its simulated motion; the body follows the run's motion, so a run
that moved on the body fitted to the capture (run.json ``body``: 'fit') is refused. Mode ``independent``: the
truth garment simulated on its own on the true body (:mod:`pgc.pipeline.independent`), whichever body the run
moved on. metrics.json records the mode and the run's body, and keeps each mode evaluated on the same renders
under ``modes``; its top level is the appearance result when there is one.
For a folder of images, ``frame_XXXX_CAMERA.png`` files are compared directly.
Light: the ground truth is lit as the renders were (``render.json`` field ``light``,
:mod:`pgc.io.light_record`): the capture light, or the same environment map file turned by the same angle per
frame, scaled by the capture's true radiance. What cannot be reproduced or checked is refused.
Metrics are restricted to the garment: the union of the ground-truth garment coverage and the rendered
alpha (both over black).
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
from pgc.io.limits import read_json
from pgc.pipeline.animate import read_run
from pgc.pipeline.runner import StageContext, StageRunner, Step
from pgc.pipeline.stage_io import save_npz
from pgc.stages import eval as eval_stage

VARIANTS = {"hybrid": "hybrid", "3dgs_only": "near", "pbr_only": "pbr"}
"""Metric key -> the render layer it evaluates."""


RENDER_INPUTS = "inputs.json"
"""Written into ``RUN/render/`` by ``pgc render``: the hashes of the simulation the frames were rendered from."""


def render_inputs(run_dir: Path) -> dict[str, str]:
    """Content hashes of the run files a render depends on (the simulated garment and the body motion)."""
    from pgc.pipeline.cache import file_key

    return {name: file_key(run_dir / name) for name in ("garment.npz", "body.npz")}


def rendered_frames(run_dir: Path) -> tuple[dict[str, Any], list[int]]:
    """The render metadata and frame numbers of a run, after checking that they are well-formed, that every
    frame file is there and that they were rendered from the run's current simulation."""
    meta_path = run_dir / "render" / "render.json"
    fix = f"run 'pgc render {run_dir}' (again)"
    if not meta_path.is_file():
        raise PGCDataError(f"{run_dir}: no rendered frames (render/render.json); run 'pgc render {run_dir}' first")
    meta = read_json(meta_path, "render.json", fix=fix)
    frames = meta.get("frames") if isinstance(meta, dict) else None
    if not isinstance(frames, list) or not frames or not all(isinstance(t, int) and t >= 0 for t in frames):
        raise PGCDataError(f"{meta_path}: field 'frames' must be a non-empty list of frame numbers; {fix}")
    cameras = meta.get("cameras")
    if not isinstance(cameras, list) or not cameras or not all(isinstance(c, str) for c in cameras):
        raise PGCDataError(f"{meta_path}: field 'cameras' must be a non-empty list of camera names; {fix}")
    missing = [t for t in frames if not (run_dir / "render" / f"frame_{t:04d}.npz").is_file()]
    if missing:
        raise PGCDataError(f"{run_dir / 'render'}: frames {missing[:8]} listed in render.json are missing; {fix}")
    recorded = meta.get("inputs")
    if recorded is None and (run_dir / "render" / RENDER_INPUTS).is_file():
        recorded = read_json(run_dir / "render" / RENDER_INPUTS, RENDER_INPUTS, fix=fix)
    if recorded is not None and recorded != render_inputs(run_dir):
        raise PGCDataError(f"{run_dir / 'render'}: the frames were rendered from an earlier simulation of this run "
                           f"(garment.npz/body.npz changed since, e.g. re-animated with another motion); {fix}")
    return meta, list(frames)


def ground_truth_key(run_dir: Path, capture_dir: Path, camera_names: list[str], cfg: RunConfig,
                     light: dict[str, Any] | None = None, mode: str = "appearance") -> str:
    """The cache key of a run's ground-truth renders: the eval stage's version, the run's simulation, the cameras,
    the capture's scene, the configuration's scene renderer (implementation, options, version) and the light's
    identity (:func:`pgc.io.light_record.identity`; default the capture light), so relit and unrelit truth never
    mix, and the evaluation mode (independent: with the truth simulation's settings)."""
    from pgc.pipeline.cache import content_key, file_key

    scene = file_key(capture_dir / "ground_truth" / "scene.json")
    return content_key("gt", eval_stage.STAGE.version, file_key(run_dir / "garment.npz"),
                       file_key(run_dir / "body.npz"), camera_names, scene, cfg.role_key("scene_renderer"),
                       light or {"kind": "capture"}, *_mode_key(cfg, mode))


def _mode_key(cfg: RunConfig, mode: str) -> tuple[Any, ...]:
    """The mode's part of the ground-truth key (nothing for appearance: its keys predate the modes)."""
    if mode == "appearance":
        return ()
    settings = cfg.stage("eval")
    return (mode, settings.truth_simulator, settings.truth_resolution, settings.truth_options)


def check_scene_renderer_light(renderer: Any, record: dict[str, Any], cfg: RunConfig) -> None:
    """Refuse a light ``renderer`` (the configuration's scene renderer) does not declare in ``light_kinds``."""
    from pgc.io.light_record import SCENE_LIGHT, describe

    need = SCENE_LIGHT.get(record["kind"], record["kind"])
    kinds = tuple(getattr(renderer, "light_kinds", ("constant",)))
    if need not in kinds:
        name = cfg.role_key("scene_renderer")["name"]
        raise PGCDataError(f"the frames were lit by {describe(record)}, which the scene renderer '{name}' cannot "
                           f"reproduce (it renders {', '.join(kinds)} lights); choose a [scene_renderer] that "
                           f"renders '{need}' lights, or evaluate frames rendered under the capture light "
                           "(pgc render RUN without --light)")


def synthetic_ground_truth(run_dir: Path, capture_dir: Path, frames: list[int], camera_names: list[str],
                           cfg: RunConfig, reporter: Reporter,
                           light: dict[str, Any] | None = None, mode: str = "appearance",
                           registry: Any = None) -> list[dict[str, np.ndarray]]:
    """Ground-truth renders of the run's frames by ``cfg``'s scene renderer under ``light`` (a checked record of
    :func:`pgc.io.light_record.render_light`; default the capture light; an environment map is scaled by the
    capture's true radiance and turned per frame), cached in ``RUN/gt/<ground_truth_key>`` with the light's
    public record (``light.json``); each frame is also kept across runs (:mod:`pgc.pipeline.truth_cache`).
    ``mode``: the truth garment on the run's geometry ('appearance') or simulated on its own ('independent', its
    simulator found in ``registry``, default the installed plugins); either way kept as clear of the true body as
    it rested (:func:`pgc.pipeline.transfer.clear_of_body`). Each view is rendered in passes of
    ``[stages.eval] gt_spp`` samples until its garment's relative noise reaches ``gt_noise`` or ``gt_max_spp`` samples
    (:func:`pgc.synth.frames.converged_color`); a frame's 'spp' and 'noise' say what each view spent and reached."""
    from pgc.io.asset import read_asset
    from pgc.io.capture import read_capture
    from pgc.io.images import read_envmap
    from pgc.io.light_record import GT_LIGHT_FILE, capture_record, identity, public, rotation_at
    from pgc.pipeline.transfer import clear_of_body, embed, place, rest_clearance
    from pgc.pipeline.truth_cache import TruthFrameCache, light_at
    from pgc.synth.frames import GT_SAMPLER, GT_SAMPLES, render_frames, sampling_tag
    from pgc.synth.ground_truth import read_ground_truth
    from pgc.synth.render import scene_renderer
    from pgc.types import Light

    light = light or capture_record()
    renderer = None
    if light["kind"] != "capture":  # refused before anything is read or rendered
        renderer = scene_renderer(cfg)
        check_scene_renderer_light(renderer, light, cfg)
    key = ground_truth_key(run_dir, capture_dir, camera_names, cfg, identity(light, frames), mode)
    cache = run_dir / "gt" / key  # never a stale frame
    settings = cfg.stage("eval")
    sampling = sampling_tag(settings.gt_spp, settings.gt_noise, settings.gt_max_spp)
    paths = [cache / f"frame_{t:04d}_{sampling}.npz" for t in frames]
    if all(p.is_file() for p in paths):
        return [dict(np.load(p)) for p in paths]
    meta = read_run(run_dir)
    asset = read_asset(meta["asset"])
    gt = read_ground_truth(capture_dir)
    by_name = {c.name: c for c in read_capture(capture_dir).cameras}
    missing = [n for n in camera_names if n not in by_name]
    if missing:
        raise PGCDataError(f"ground truth {capture_dir}: cameras {missing} of the run are not in the capture")
    cameras = [by_name[n] for n in camera_names]
    garment = np.load(run_dir / "garment.npz")["vertices"]
    body = np.load(run_dir / "body.npz")["vertices"]
    if max(frames) >= len(garment) or len(body) != len(garment):
        raise PGCDataError(f"{run_dir}: rendered frames {frames} do not match the simulated frames "
                           f"({len(garment)} garment, {len(body)} body)")
    if mode == "independent":
        from pgc.pipeline.independent import independent_garment

        gt_garment, body_frames, _ = independent_garment(gt.garment, run_dir, capture_dir, frames, cfg.stage("eval"),
                                                         registry, reporter, lambda: cfg.create("body_model"))
    else:
        embedding = embed(gt.garment.vertices, asset.garment)
        gt_garment, body_frames = np.stack([place(embedding, asset.garment, garment[t]) for t in frames]), body[frames]
    clearance = rest_clearance(gt.garment.vertices, gt.body)
    gt_garment = np.stack([clear_of_body(g, b, gt.body.faces, clearance) for g, b in zip(gt_garment, body_frames)])
    lights = [gt.light] * len(frames)
    if light["kind"] == "envmap":
        envmap = read_envmap(light.get("path") or light["file"])
        lights = [Light(gt.light.radiance, envmap=envmap, rotation_deg=rotation_at(light, t)) for t in frames]
    renderer = renderer or scene_renderer(cfg)
    kept = TruthFrameCache.open(capture_dir, cfg.role_key("scene_renderer"), type(renderer), sampling, GT_SAMPLES,
                                GT_SAMPLER)
    keys = [kept.key(gt_garment[i], body_frames[i], cameras, light_at(light, t), i) for i, t in enumerate(frames)]
    out = [kept.load(k) for k in keys]
    todo = [i for i, frame in enumerate(out) if frame is None]  # frame i is seeded by i, as in the whole sequence
    if todo:
        rendered = render_frames(gt, gt_garment[todo], body_frames[todo], cameras, [lights[i] for i in todo],
                                 spp=settings.gt_spp, gt_samples=GT_SAMPLES, sampler=GT_SAMPLER, reporter=reporter,
                                 renderer=renderer, frame_seeds=todo, noise=settings.gt_noise,
                                 max_spp=settings.gt_max_spp,
                                 on_frame=lambda j, frame: kept.store(keys[todo[j]], frame))  # kept as it is done
        for i, frame in zip(todo, rendered):
            out[i] = frame
    for p, frame in zip(paths, out):
        save_npz(p, **frame)
    write_json(cache / GT_LIGHT_FILE, public(light, frames))  # which light, for the report
    return out


def truth_sampling(truth: list[dict[str, np.ndarray]], settings: eval_stage.EvalSettings) -> dict[str, Any]:
    """What the truth's views spent and reached: samples per pass, noise target and most samples (the eval stage's
    settings), the samples per frame and view and, with a noise target, the relative noise each view reached and
    the largest (None: one pass, not measured)."""
    noise = [[float(x) for x in f["noise"]] for f in truth] if all("noise" in f for f in truth) else None
    return {"spp_per_pass": settings.gt_spp, "noise_target": settings.gt_noise, "max_spp": settings.gt_max_spp,
            "spp": [[int(x) for x in f["spp"]] for f in truth], "noise": noise,
            "largest_noise": max(max(row) for row in noise) if noise else None}


@dataclass(frozen=True)
class EvalInputs:
    """What the eval stage reads: the run folder, its checked render metadata, frames and light record, the
    ground truth (a synthetic capture or an image folder), where the metrics go (None: RUN/metrics.json), the
    evaluation mode (:data:`pgc.stages.eval.MODES`) and the registry of the truth simulator (None: the
    installed plugins)."""

    run_dir: Path
    gt: Path
    meta: dict[str, Any]
    frames: list[int]
    light: dict[str, Any]
    out: Path | None
    mode: str = "appearance"
    registry: Any = None


def compute_eval(ctx: StageContext[EvalInputs], folder: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Every configured metric of every variant against the ground truth, per frame and mean; written to
    ``out`` (default ``folder/metrics.json``, the run folder)."""
    from pgc.io.light_record import public

    inp, cfg, reporter = ctx.inputs, ctx.cfg, ctx.reporter
    run_dir, gt, meta, frames, light = inp.run_dir, inp.gt, inp.meta, inp.frames, inp.light
    fix = f"run 'pgc render {run_dir}' (again)"
    metrics = cfg.roles["metric"].create_all()
    truth_figures = sampling = None
    capture = synthetic_capture(gt)
    if capture is not None:
        truth = synthetic_ground_truth(run_dir, capture, frames, meta["cameras"], cfg,
                                       reporter, light, inp.mode, inp.registry)
        targets = [(f["color"] * f["garment_mask"][..., None], f["garment_mask"]) for f in truth]
        sampling = truth_sampling(truth, cfg.stage("eval"))
        if inp.mode == "independent":
            from pgc.pipeline.independent import truth_simulation

            truth_figures = truth_simulation(run_dir, capture, cfg.stage("eval"), inp.registry,
                                             pose_body=lambda: cfg.create("body_model"))[2]
    else:
        if inp.mode != "appearance":
            raise PGCDataError(f"--gt {gt}: a folder of images cannot be evaluated in mode '{inp.mode}' (it needs a "
                               "synthetic capture whose garment can be simulated); give the capture folder")
        check_folder_light(gt, light, frames, run_dir)
        targets = [_image_folder_frame(gt, t, meta["cameras"]) for t in frames]
    per_frame: dict[str, list[dict[str, float]]] = {k: [] for k in VARIANTS}
    with reporter.stage("eval", total=len(frames)) as st:
        for i, t in enumerate(frames):
            pred = read_frame(run_dir / "render" / f"frame_{t:04d}.npz", fix)
            target, coverage = targets[i]
            if target.shape != pred["hybrid"].shape:
                raise PGCDataError(f"frame {t}: ground truth {target.shape} and render {pred['hybrid'].shape} "
                                   "differ in size; render and ground truth must use the same cameras")
            for key, layer in VARIANTS.items():
                alpha = pred[layer_alpha(layer, pred)]
                row = {"frame": t}
                for name, metric in metrics.items():
                    vals = [metric(pred[layer][c], target[c], eval_region(coverage[c], alpha[c]))
                            for c in range(len(target))]
                    row[name] = float(np.mean(vals))
                per_frame[key].append(row)
            st.progress(i + 1)
    result: dict[str, Any] = {"run": str(run_dir), "ground_truth": str(gt), "frames": frames,
                              "cameras": meta["cameras"], "kernel_size": meta.get("kernel_size"),
                              "light": public(light, frames), "mode": inp.mode, "body": run_body(run_dir),
                              "render_inputs": render_inputs(run_dir)}
    if sampling is not None:
        result["truth_sampling"] = sampling
    if truth_figures is not None:
        result["truth_simulation"] = truth_figures
    for key, rows in per_frame.items():
        result[key] = {name: float(np.mean([r[name] for r in rows])) for name in metrics}
        result[key]["per_frame"] = rows
    write_json(inp.out or folder / "metrics.json", with_modes(inp.out or folder / "metrics.json", result))
    return result, {}


def with_modes(path: Path, result: dict[str, Any]) -> dict[str, Any]:
    """The metrics document to write at ``path``: field ``modes`` holds the means of every mode evaluated on the
    same renders (same simulation, frames, cameras and light; kept from the file already there), the top level
    is the appearance result when there is one, else ``result``."""
    keep = ("frames", "cameras", "light", "render_inputs")
    prev: dict[str, Any] = {}
    if path.is_file():
        try:
            prev = read_json(path, "metrics.json")
        except PGCDataError:
            prev = {}  # unreadable: replaced
    same = isinstance(prev, dict) and isinstance(prev.get("modes"), dict) and all(
        prev.get(k) == result.get(k) for k in keep)
    modes = dict(prev["modes"]) if same else {}
    modes[result["mode"]] = {k: ({m: x for m, x in v.items() if m != "per_frame"} if k in VARIANTS else v)
                             for k, v in result.items() if k in VARIANTS or k == "truth_simulation"}
    top = prev if same and result["mode"] != "appearance" and prev.get("mode") == "appearance" else result
    return {**{k: v for k, v in top.items() if k != "modes"}, "modes": modes}


def synthetic_capture(gt: Path) -> Path | None:
    """The synthetic capture that ``--gt`` names (its folder, or its ``ground_truth`` folder); None for a folder of
    images."""
    if (gt / "ground_truth").is_dir():
        return gt
    return gt.parent if (gt / "scene.json").is_file() else None


def run_body(run_dir: Path) -> str | None:
    """The body the run's garment moved on (run.json ``body``): 'truth', 'fit', or None for a motion file of body
    vertices; a run recorded before runs named it moved on the capture's true body."""
    meta = read_run(run_dir)
    return meta["body"] if "body" in meta else "truth"


def check_appearance_body(run_dir: Path, gt: Path) -> None:
    """Refuse to judge appearance on the geometry of a run that moved on the body fitted to the capture: the truth
    garment would be carried along a simulation on a body that is not the truth's."""
    if synthetic_capture(gt) is not None and run_body(run_dir) == "fit":
        raise PGCDataError(f"{run_dir}: the run's garment moved on the body fitted to the capture (run.json 'body': "
                           "'fit'), and mode 'appearance' carries the truth garment along the run's own simulation; "
                           f"evaluate it with 'pgc eval {run_dir} --gt {gt} --mode independent' (the truth simulated "
                           "on the true body), or animate an asset reconstructed with 'pgc reconstruct --body truth'")


STAGES = ((eval_stage.STAGE, Step(compute_eval)),)
"""The stages of ``pgc eval``, each with its code."""


def evaluate_run(run_dir: str | Path, gt: str | Path, cfg: RunConfig, reporter: Reporter | None = None,
                 out: str | Path | None = None, mode: str = "appearance", registry: Any = None) -> dict[str, Any]:
    """Metrics per frame and mean for every variant in ``mode`` ('appearance' or 'independent'), with the light the
    renders and the ground truth share (field ``light``); written to ``out`` (default RUN/metrics.json) beside the
    other mode's means (:func:`with_modes`). ``registry``: where the independent truth's simulator is found."""
    from pgc.pipeline.cache import StageCache
    from pgc.pipeline.independent import check_mode

    check_mode(mode)

    run_dir, gt = Path(run_dir), Path(gt)
    if mode == "appearance":
        check_appearance_body(run_dir, gt)
    meta, frames = rendered_frames(run_dir)
    fix = f"run 'pgc render {run_dir}' (again)"
    for t in frames:  # before the ground truth is rendered
        check_frame_arrays(run_dir / "render" / f"frame_{t:04d}.npz", fix)
    inputs = EvalInputs(run_dir, gt, meta, frames, run_light(run_dir, meta, frames), Path(out) if out else None,
                        mode, registry)
    runner = StageRunner(StageCache(run_dir), StageContext(cfg, reporter or Reporter.silent(), inputs), {})
    for stage, step in STAGES:
        runner.run(stage, step)
    return runner.ctx.values["eval"]


def run_light(run_dir: Path, meta: dict[str, Any], frames: list[int]) -> dict[str, Any]:
    """The checked light record of the run's renders (:func:`pgc.io.light_record.render_light`)."""
    from pgc.io.light_record import render_light

    fix = (f"render again with 'pgc render {run_dir} --light ENV.exr [--rotate-light]' (or without --light for "
           "the capture light)")
    return render_light(meta, run_dir / "render" / "render.json", frames, fix)


def check_folder_light(folder: Path, light: dict[str, Any], frames: list[int], run_dir: Path) -> None:
    """Refuse a folder of ground-truth images lit otherwise than the renders: its ``light.json`` must give the
    same light on every evaluated frame; without one, only renders of the capture light are compared."""
    from pgc.io.light_record import GT_LIGHT_FILE, check_record, describe, same_light

    path = folder / GT_LIGHT_FILE
    if not path.is_file():
        if light["kind"] != "capture":
            raise PGCDataError(f"ground-truth folder {folder}: no {GT_LIGHT_FILE} says which light its images were "
                               f"rendered under, and the run's frames were lit by {describe(light)}; add "
                               f"{GT_LIGHT_FILE} (the light record of docs/pipeline.md, 'Relit evaluation') or "
                               "give a synthetic capture as --gt")
        return
    fix = f"give ground truth rendered under the run's light, or render {run_dir} under the folder's"
    doc = read_json(path, GT_LIGHT_FILE, fix=fix)
    record = check_record(doc, str(path), fix)
    if not same_light(record, light, frames):
        raise PGCDataError(f"ground-truth folder {folder}: its images were rendered under {describe(record)} "
                           f"({GT_LIGHT_FILE}), the run's frames under {describe(light)}; {fix}")


FRAME_ARRAYS = ("hybrid", "near", "pbr", "alpha", "pbr_alpha")
"""The arrays every rendered frame file holds for evaluation (the layers of :data:`VARIANTS` and their alphas)."""


def check_frame_arrays(path: Path, fix: str) -> list[str]:
    """The array names of the rendered frame file ``path`` (read from its index, no data), once it is a
    readable archive holding every one of :data:`FRAME_ARRAYS`; else an error naming the file and the array."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as z:
            names = list(z.files)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise PGCDataError(f"{path}: not a readable rendered frame ({type(exc).__name__}: {exc}); {fix}") from None
    absent = [k for k in FRAME_ARRAYS if k not in names]
    if absent:
        raise PGCDataError(f"{path}: the rendered frame has no array {', '.join(repr(k) for k in absent)} "
                           f"(it holds {', '.join(names) or 'none'}); {fix}")
    return names


def read_frame(path: Path, fix: str) -> dict[str, np.ndarray]:
    """Every array of the rendered frame file ``path`` (each read once), checked by :func:`check_frame_arrays`."""
    check_frame_arrays(path, fix)
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def layer_alpha(layer: str, frame) -> str:
    """The key of the alpha that shapes ``layer`` in a rendered frame (``hybrid_alpha`` is absent in runs
    rendered before the hybrid could take the far field's silhouette: there it was the near field's)."""
    if layer == "pbr":
        return "pbr_alpha"
    if layer == "hybrid" and "hybrid_alpha" in frame:
        return "hybrid_alpha"
    return "alpha"


def eval_region(coverage: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W) float32 weights the metrics are restricted to: the true garment coverage or the variant's alpha."""
    return ((coverage > 0.5) | (alpha > 0.5)).astype(np.float32)


def _image_folder_frame(folder: Path, t: int, cameras: list[str]) -> tuple[np.ndarray, np.ndarray]:
    from pgc.io.images import read_image

    imgs, covs = [], []
    for name in cameras:
        path = folder / f"frame_{t:04d}_{name}.png"
        if not path.is_file():
            raise PGCDataError(f"ground-truth folder {folder}: missing {path.name} (expected frame_XXXX_CAMERA.png "
                               "for every rendered frame and camera)")
        img = read_image(path)
        imgs.append(img[..., :3])
        covs.append(np.ones(img.shape[:2], np.float32))
    return np.stack(imgs), np.stack(covs)
