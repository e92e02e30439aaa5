"""Ground truth for new frames: the scene's ground-truth materials on given garment and body vertices,
rendered from given cameras and lights (novel-pose ground truth on simulated geometry)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.synth.ground_truth import GroundTruth, read_ground_truth
from pgc.types import Camera, Light

if TYPE_CHECKING:
    from pgc.roles.scene_renderer import SceneRenderer

DEFAULT_FRAME_SPP = 64
DEFAULT_MAX_SPP = 1024
GT_SAMPLES = 2
"""Sub-pixel ray-cast samples per axis of a frame's ground-truth layers (mask, garment coverage, labels)."""
GT_SAMPLER = "ldsampler"
"""Mitsuba's sampler of a frame's colour (the low-discrepancy sampler: powers of 4 samples)."""


def _as_sequence(name: str, array: np.ndarray, vertex_count: int) -> np.ndarray:
    a = np.asarray(array, dtype=np.float64)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (vertex_count, 3):
        raise PGCDataError(f"render_frames: {name} must have shape (T, {vertex_count}, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PGCDataError(f"render_frames: {name} has non-finite values")
    return a


def sampling_tag(spp: int, noise: float = 0.0, max_spp: int = DEFAULT_MAX_SPP) -> str:
    """How a truth frame is sampled, as a file-name part: ``spp64`` for one pass, ``spp64-noise0.05-max1024``
    for passes to a noise target."""
    return f"spp{spp}" if noise <= 0 else f"spp{spp}-noise{noise:g}-max{max_spp}"


def pass_seed(base: int, index: int) -> int:
    """The seed of sampling pass ``index`` of a render whose first pass is seeded by ``base`` (31 bits)."""
    if index == 0:
        return base
    return int(np.random.SeedSequence([base, index]).generate_state(1)[0] >> 1)


def relative_noise(passes: list[np.ndarray], weight: np.ndarray) -> float:
    """The relative Monte Carlo noise of the mean of ``passes`` (equal-sample renders (H, W, 3) of one view with
    independent seeds): the root mean square over the pixels, weighted by ``weight`` (H, W) (the garment's
    coverage), of each pixel's standard error (the passes' unbiased variance over their count), divided by the
    weighted mean of the mean image. 0 when nothing is weighted or the weighted pixels are black."""
    stack = np.asarray(passes, np.float64)
    if len(stack) < 2:
        raise ValueError("relative_noise: the noise of a mean needs at least two passes")
    w = np.asarray(weight, np.float64)
    total = w.sum()
    if total <= 0:
        return 0.0
    brightness = float((w * stack.mean(0).mean(-1)).sum() / total)
    if brightness <= 1e-12:
        return 0.0
    error = stack.var(0, ddof=1).mean(-1) / len(stack)
    return float(np.sqrt((w * error).sum() / total) / brightness)


def converged_color(renderer: SceneRenderer, scene: Any, camera: Camera, spp: int, seed: int, sampler: str,
                    weight: np.ndarray, noise: float = 0.0, max_spp: int | None = None
                    ) -> tuple[np.ndarray, int, float | None]:
    """One view's colour by passes of ``spp`` samples (seeds :func:`pass_seed`), averaged: a single pass when
    ``noise`` is 0, else passes until the mean's :func:`relative_noise` over ``weight`` is at most ``noise`` or
    ``max_spp`` samples are spent (at least two passes, which the estimate needs). Returns the colour, the
    samples spent and the noise reached (None for a single pass, whose noise is not measured)."""
    passes = [renderer.render_color(scene, camera, spp, seed, sampler)[0]]
    reached = None
    if noise > 0:
        budget = max(2, (max_spp or spp) // spp)
        while len(passes) < budget:
            passes.append(renderer.render_color(scene, camera, spp, pass_seed(seed, len(passes)), sampler)[0])
            reached = relative_noise(passes, weight)
            if reached <= noise:
                break
    color = np.mean(np.asarray(passes, np.float64), axis=0).astype(np.float32)
    return color, spp * len(passes), reached


def render_frames(scene_dir_or_gt: str | os.PathLike | GroundTruth, garment_vertices: np.ndarray,
                  body_vertices: np.ndarray, cameras: list[Camera], light: Light | list[Light] | None = None,
                  spp: int | None = None, seed: int = 0, gt_samples: int = GT_SAMPLES, sampler: str = GT_SAMPLER,
                  reporter: Reporter | None = None, *, renderer: SceneRenderer,
                  frame_seeds: list[int] | None = None, noise: float = 0.0,
                  max_spp: int | None = None,
                  on_frame: Callable[[int, dict[str, np.ndarray]], None] | None = None) -> list[dict[str, np.ndarray]]:
    """Render T frames of the ground-truth scene with new vertices, by ``renderer`` (the configuration's, see
    :func:`pgc.synth.render.scene_renderer`).

    garment_vertices (T, Vg, 3) and body_vertices (T, Vb, 3) (metres; the topology of the capture's
    ground-truth meshes); ``light`` (one for every frame, or a list of one per frame) defaults to the capture
    light; ``spp`` to 64 (of Mitsuba's ``sampler``;
    the low-discrepancy sampler needs powers of 4) per pass; ``noise`` > 0 renders each view in passes until
    its garment's relative noise is at most ``noise`` or ``max_spp`` (default 1024) samples are spent
    (:func:`converged_color`). Returns one dict per
    frame with per-camera lists: 'color' (H, W, 3) linear RGB over the light's background, 'alpha' (H, W)
    coverage, 'garment_mask' (H, W) garment coverage, 'segmentation' (H, W) labels, 'spp' the samples spent
    and, with a ``noise`` target, 'noise' the relative noise reached. Fibres and the
    near-field detail follow the garment (both are embedded in its faces). The first pass of frame ``t`` and
    camera ``c`` is seeded by ``seed * 100003 + frame_seeds[t] * 1009 + c`` (``frame_seeds`` default
    ``0 .. T-1``), so that a subset of a sequence renders as it does within it. ``on_frame(t, frame)`` is called
    as each frame is done (to keep it before the next one starts: an interrupted render loses one frame at most).
    """
    gt = scene_dir_or_gt if isinstance(scene_dir_or_gt, GroundTruth) else read_ground_truth(scene_dir_or_gt)
    gv = _as_sequence("garment_vertices", garment_vertices, len(gt.garment.vertices))
    bv = _as_sequence("body_vertices", body_vertices, len(gt.body.vertices))
    if len(gv) != len(bv):
        raise PGCDataError(f"render_frames: {len(gv)} garment frames but {len(bv)} body frames")
    if not cameras:
        raise PGCDataError("render_frames: no cameras given")
    lights = light if isinstance(light, list) else [light or gt.light] * len(gv)
    if len(lights) != len(gv):
        raise PGCDataError(f"render_frames: {len(lights)} lights for {len(gv)} frames")
    spp = DEFAULT_FRAME_SPP if spp is None else int(spp)
    if not 0.0 <= noise < 1.0:
        raise PGCDataError(f"render_frames: noise {noise} must be in [0, 1) (relative; 0 renders one pass)")
    max_spp = DEFAULT_MAX_SPP if max_spp is None else int(max_spp)
    frame_seeds = list(range(len(gv))) if frame_seeds is None else [int(n) for n in frame_seeds]
    if len(frame_seeds) != len(gv):
        raise PGCDataError(f"render_frames: {len(frame_seeds)} frame seeds for {len(gv)} frames")
    reporter = reporter or Reporter.silent()
    frames = []
    with reporter.stage("render_gt_frames", total=len(gv), spp=spp) as st:
        for t in range(len(gv)):
            geometry = gt.geometry(gv[t], bv[t])
            scene, labels = renderer.build_scene(geometry, lights[t])
            out: dict[str, list[Any]] = {"color": [], "alpha": [], "garment_mask": [], "segmentation": [],
                                         "spp": [], **({"noise": []} if noise > 0 else {})}
            for c, cam in enumerate(cameras):
                layers = renderer.ground_truth_layers(scene, labels, geometry, cam, gt_samples)
                color, spent, reached = converged_color(renderer, scene, cam, spp,
                                                        seed * 100003 + frame_seeds[t] * 1009 + c, sampler,
                                                        layers["garment_coverage"], noise, max_spp)
                out["color"].append(color)
                out["spp"].append(spent)
                if reached is not None:
                    out["noise"].append(reached)
                out["alpha"].append(layers["mask"])
                out["garment_mask"].append(layers["garment_coverage"])
                out["segmentation"].append(layers["segmentation"])
            frames.append({k: np.stack(v) for k, v in out.items()})
            if on_frame is not None:
                on_frame(t, frames[-1])
            st.progress(t + 1)
    return frames


def render_frames_files(gt_dir: str | os.PathLike, garment_npz: str | os.PathLike, body_npz: str | os.PathLike,
                        out_dir: str | os.PathLike, cameras: list[Camera] | None = None,
                        light: Light | None = None, spp: int | None = None,
                        reporter: Reporter | None = None, *, renderer: SceneRenderer, noise: float = 0.0,
                        max_spp: int | None = None) -> list[Path]:
    """File front end of :func:`render_frames` (``pgc synth render-frames``): vertices from .npz files
    (key 'vertices', (T, V, 3)), cameras from the capture (default), one .npz per frame written to
    ``out_dir`` (color, alpha, garment_mask, segmentation: stacked over cameras) plus sRGB PNGs; under the
    capture light (``light`` None) also ``light.json`` (:mod:`pgc.io.light_record`), which ``pgc eval`` compares
    with a run's render light when the folder is its ``--gt``."""
    from pgc.io.atomic import atomic_open
    from pgc.io.capture import read_capture
    from pgc.io.images import write_image

    def load(path) -> np.ndarray:
        path = Path(path)
        if not path.is_file():
            raise PGCDataError(f"{path}: no such file; give an .npz with key 'vertices' (T, V, 3)")
        with np.load(path) as z:
            if "vertices" not in z:
                raise PGCDataError(f"{path}: missing key 'vertices' (T, V, 3); keys: {list(z.keys())}")
            return z["vertices"]

    if cameras is None:
        cameras = read_capture(gt_dir).cameras
    frames = render_frames(gt_dir, load(garment_npz), load(body_npz), cameras, light, spp, reporter=reporter,
                           renderer=renderer, noise=noise, max_spp=max_spp)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for t, frame in enumerate(frames):
        path = out_dir / f"frame_{t:04d}.npz"
        with atomic_open(path, "wb") as f:
            np.savez_compressed(f, **frame, camera_names=np.array([c.name for c in cameras]))
        for c, cam in enumerate(cameras):
            write_image(out_dir / f"frame_{t:04d}_{cam.name}.png", frame["color"][c])
        written.append(path)
    if light is None:
        from pgc.io.atomic import write_json
        from pgc.io.light_record import GT_LIGHT_FILE, capture_record

        write_json(out_dir / GT_LIGHT_FILE, capture_record())
    return written
