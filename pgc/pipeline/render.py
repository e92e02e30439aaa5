"""``pgc render``: hybrid rendering of an animated run (docs/method.md, "Hybrid rendering"), with its ablations.

Per rendered frame and camera: the near field ``G_t`` (the optimised Gaussians on the simulated garment),
the far field ``S_t`` (the Gaussians coloured by the PBR renderer's texture-space radiance ``T_t``), the
hybrid ``h(G_t) + l(S_t)``, and the PBR-only ablation (the mesh rendered by the PBR renderer). The low-pass
kernel (and, with ``far_source = 'auto'``, the far field) is chosen once per asset on the training frame (the
capture pose) by the configured rule: :func:`choose_kernel` returns a :class:`KernelDecision` that the frames
are rendered with; nothing is set on shared objects.
Output: ``RUN/render/frame_XXXX.npz`` (arrays stacked over cameras) and ``RUN/render/render.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from pgc.config import RunConfig
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.filtering.detail import CAPTURE_FAR_FIELD_MODES
from pgc.geometry.raster import rasterize
from pgc.io.atomic import write_json
from pgc.pipeline.animate import read_run
from pgc.pipeline.cache import StageCache, array_key, asset_key, file_key
from pgc.pipeline.compose import (compose, far_field_gaussians, gaussian_uvs, hide_behind, unpremultiply,
                                  visible_surface_uvs)
from pgc.pipeline.garment import body_occluder
from pgc.pipeline.runner import StageContext, StageRunner, Step
from pgc.pipeline.stage_io import save_npz
from pgc.roles.splat_renderer import RenderOutput
from pgc.sampling import spread
from pgc.splats.binding import bind
from pgc.stages import render as render_stage
from pgc.types import Camera, Capture, GarmentAsset, Light, Mesh


@dataclass(frozen=True)
class KernelDecision:
    """What the kernel rule decided on the training frame: the low-pass kernel size (odd, px) and the far field
    (``'splats'`` or ``'mesh'``), with the figures that justify them."""

    kernel_size: int
    far_source: str
    criterion: str
    per_view: list[int] = field(default_factory=list)
    far_errors: dict[str, float] = field(default_factory=dict)
    kernel_views: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"kernel_size": self.kernel_size, "far_source": self.far_source, "criterion": self.criterion,
                "per_view": list(self.per_view), "far_errors": dict(self.far_errors),
                "kernel_views": list(self.kernel_views)}


class HybridRenderer:
    """Renders one garment state from one camera with the configured splat renderer, PBR renderer and filter.
    Holds only what every frame shares (the asset, the roles, the stage settings); the light, the far field
    and the kernel are arguments."""

    def __init__(self, asset: GarmentAsset, cfg: RunConfig) -> None:
        self.asset = asset
        self.splats = cfg.create("splat_renderer")
        self.pbr = cfg.create("pbr_renderer")
        self.filter = cfg.create("filter")
        self.settings = cfg.stage("render")
        self.uvs = gaussian_uvs(asset.gaussians, asset.garment)

    def mesh_at(self, vertices: np.ndarray) -> Mesh:
        g = self.asset.garment
        return Mesh(vertices, g.faces, g.uv, g.face_uv, g.face_labels, name="garment")

    def layers(self, vertices: np.ndarray, camera: Camera, light: Light, far_source: str,
               occluder: Mesh | None = None) -> dict[str, Any]:
        """Near-field, far-field and PBR-only renders of the garment at ``vertices`` under ``light`` (before
        composition); ``far_source`` 'splats' (the far field also renders the PBR-only image) or 'mesh' (the far
        field is the PBR-only image); ``occluder`` (the body in the same frame) shadows the far field and, with
        ``body_occludes``, hides the garment where it is in front."""
        mesh = self.mesh_at(vertices)
        faces = self.asset.garment.faces
        world = bind(self.asset.gaussians, vertices, faces)
        near = self.splats.render(world, camera)
        raster = rasterize(camera, vertices, faces)
        hides = occluder if self.settings.body_occludes else None

        def far_field(lit: Light) -> tuple[RenderOutput, RenderOutput]:
            """The far field and the PBR-only render under ``lit``."""
            pbr = self.pbr.render(mesh, self.asset.material, lit, camera, occluder=hides)
            if far_source != "splats":
                return pbr, pbr
            size = self.settings.texture_size
            texture, _ = self.pbr.render_texture(mesh, self.asset.material, lit, camera, (size, size),
                                                 occluder=occluder)
            uvs = self.uvs
            if self.settings.far_lookup == "visible":
                uvs = visible_surface_uvs(world.means, raster, mesh, camera, self.uvs)
            return self.splats.render(bind(far_field_gaussians(self.asset.gaussians, uvs, texture), vertices,
                                           faces), camera), pbr

        far, pbr = far_field(light)
        # detail 'ratio' or 'residual' under a novel light: the far field under the capture light too
        far_capture = None
        if self.settings.detail in CAPTURE_FAR_FIELD_MODES and not same_light(light, self.asset.light):
            far_capture = far_field(self.asset.light)[0]
        if hides is not None:  # the garment's first surface decides; beyond its silhouette, the splats' depth
            depth = np.where(np.isfinite(raster.depth), raster.depth, near.depth)
            body_depth = rasterize(camera, hides.vertices, hides.faces).depth
            near = hide_behind(near, body_depth, depth)
            if far_source == "splats":  # the PBR renders are occluded by the body already
                far = hide_behind(far, body_depth, depth)
                far_capture = None if far_capture is None else hide_behind(far_capture, body_depth, depth)
        return {"near": near, "far": far, "pbr": pbr, "far_capture": far_capture}

    def frame(self, vertices: np.ndarray, camera: Camera, light: Light, decision: KernelDecision,
              occluder: Mesh | None = None) -> dict[str, np.ndarray]:
        """Every output layer of one frame and camera, composed with ``decision``'s kernel and far field."""
        lay = self.layers(vertices, camera, light, decision.far_source, occluder)
        h = compose(lay["near"], lay["far"], self.filter, decision.kernel_size, silhouette=self.settings.silhouette,
                    outline_fade=self.settings.outline_fade, detail=self.settings.detail,
                    far_capture=lay["far_capture"])
        return {"hybrid": h.hybrid, "near": h.near, "far": h.far, "pbr": lay["pbr"].color,
                "alpha": h.alpha, "hybrid_alpha": h.hybrid_alpha, "pbr_alpha": lay["pbr"].alpha,
                "low_far": h.low_far, "high_near": h.high_near}


def same_light(a: Light, b: Light) -> bool:
    """Whether ``a`` and ``b`` light a scene alike: equal radiance, environment map and rotation."""
    if not np.allclose(a.radiance, b.radiance) or (a.envmap is None) != (b.envmap is None):
        return False
    if a.envmap is None:
        return True
    return a.rotation_deg == b.rotation_deg and np.array_equal(a.envmap, b.envmap)


def kernel_views(asset: GarmentAsset, capture, count: int) -> list:
    """Up to ``count`` capture views for the kernel rule: those the splat fit held out (on views it trained on,
    the near field's error is optimistic and pulls toward large kernels), else any."""
    held = set(asset.heldout_views)
    pool = [v for v in capture.views if v.camera.name in held] or capture.views
    return spread(pool, count)


def choose_kernel(renderer: HybridRenderer, capture, cfg: RunConfig) -> KernelDecision:
    """Apply the configured kernel rule to the training frame (the capture pose, lit by the asset's fitted
    capture light, whatever light the run is rendered under) on the kernel views; with ``far_source = 'auto'``
    also choose the far field: the one whose hybrid has the lower error there (mode 'metric': the better
    score of its metric; ``far_errors`` then holds the metric's values)."""
    from pgc.albedo.base_color import garment_mask
    from pgc.filtering.auto import TrainingFrame, choose_kernel_by_metric, hybrid_error, select_kernel

    settings = cfg.stage("render")
    sources = ("splats", "mesh") if settings.far_source == "auto" else (settings.far_source,)
    rest = renderer.asset.garment.vertices
    body = body_occluder(renderer.asset.body, capture.garment_label_ids)
    views = kernel_views(renderer.asset, capture, settings.kernel_views)
    frames: dict[str, list[TrainingFrame]] = {source: [] for source in sources}
    for view in views:
        # 'splats' renders the mesh image too: one pass serves both sources
        lay = renderer.layers(rest, view.camera, renderer.asset.light, sources[0], body)
        far = {"splats": lay["far"], "mesh": lay["pbr"]} if len(sources) > 1 else {sources[0]: lay["far"]}
        near = unpremultiply(lay["near"])
        mask = garment_mask(view, capture.garment_label_ids)
        for source, f in far.items():
            frames[source].append(TrainingFrame(image=view.image, near=near, near_alpha=lay["near"].alpha,
                                                far=unpremultiply(f), far_alpha=f.alpha, mask=mask))
    decisions = {}  # source -> (its score at its size, size, choices)
    # mode 'metric': the metric plugin of the run's [metric] list (checked when the config was read)
    metric = cfg.roles["metric"].create(settings.kernel.metric) if settings.kernel.mode == "metric" else None
    for source, per_view in frames.items():
        if metric is not None:
            # one choice over all kernel views; the far fields are compared by the same metric
            choice = choose_kernel_by_metric(renderer.filter, per_view, metric, settings.kernel.metric,
                                             settings.kernel.sizes, settings.kernel.tolerance, settings.detail)
            decisions[source] = (choice.scores[choice.size], choice.size, [choice] * len(per_view))
            continue
        choices = [select_kernel(settings.kernel, renderer.filter, frame, settings.detail) for frame in per_view]
        size = int(np.median([c.size for c in choices])) | 1
        error = float(np.mean([hybrid_error(renderer.filter, frame, size, settings.detail) for frame in per_view]))
        decisions[source] = (error, size, choices)
    sign = -1.0 if metric is not None and metric.higher_is_better else 1.0
    chosen = min(decisions, key=lambda k: sign * decisions[k][0])
    _, size, choices = decisions[chosen]
    return KernelDecision(kernel_size=size, far_source=chosen, criterion=choices[0].criterion,
                          per_view=[c.size for c in choices], far_errors={k: v[0] for k, v in decisions.items()},
                          kernel_views=[v.camera.name for v in views])


def envmap_light(run_dir: str | Path, path: str | Path) -> Light:
    """An environment-map light (EXR, latitude-longitude, +Y up) scaled by the asset's fitted radiance."""
    from pgc.io.asset import read_asset
    from pgc.io.images import read_envmap

    envmap = read_envmap(path)
    asset = read_asset(read_run(run_dir)["asset"])
    return Light(asset.light.radiance, envmap=envmap)


def light_record(light: Light | None, light_file: str | Path | None, asset_light: Light, frames: list[int],
                 rotations: list[float]) -> dict[str, Any]:
    """The record of the light the frames are rendered under (:mod:`pgc.io.light_record`): the capture light
    (``light`` None, or a constant light equal to the asset's fitted one), an environment map read from
    ``light_file`` with the rotation of each frame (degrees), or, for a light ``pgc eval`` cannot reproduce (an
    environment map given without its file, another constant light), its kind without a file."""
    from pgc.io.light_record import capture_record, envmap_record

    if light is None or (light.envmap is None and np.allclose(light.radiance, asset_light.radiance)):
        return capture_record()
    if light.envmap is None:
        return {"kind": "constant", "radiance": light.radiance.tolist()}
    if light_file is None:
        return {"kind": "envmap", "file": None}
    if len(set(rotations)) > 1:
        return envmap_record(light_file, frames, rotations)
    return envmap_record(light_file, frames, rotations[0] if rotations else light.rotation_deg)


@dataclass(frozen=True)
class RenderInputs:
    """What the render stage reads: the run folder, its asset and capture, the hybrid renderer, the light (None:
    the asset's fitted light) and how the kernel is decided."""

    run_dir: Path
    asset: GarmentAsset
    capture: Capture
    renderer: HybridRenderer
    light: Light | None
    light_file: str | Path | None
    rotate_light: bool
    decide: Callable[[HybridRenderer, Capture], KernelDecision] | None


def compute_render(ctx: StageContext[RenderInputs], folder: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Decide the kernel on the training frame, then render every ``frame_stride``-th frame from ``views``
    cameras into ``folder`` (``frame_XXXX.npz`` and ``render.json``)."""
    from pgc.pipeline.evaluate import render_inputs

    inp, reporter, settings = ctx.inputs, ctx.reporter, ctx.cfg.stage("render")
    run_dir, asset, renderer = inp.run_dir, inp.asset, inp.renderer
    run_light = inp.light or asset.light
    with reporter.stage("choose_kernel") as st:
        kernel = inp.decide(renderer, inp.capture) if inp.decide else choose_kernel(renderer, inp.capture, ctx.cfg)
        st.record(kernel_size=kernel.kernel_size, far_source=kernel.far_source)
    vertices = np.load(run_dir / "garment.npz")["vertices"]
    with np.load(run_dir / "body.npz") as z:
        body_vertices, body_faces = z["vertices"], z["faces"]
    frames = list(range(0, len(vertices), settings.frame_stride))
    rotations = [360.0 * i / len(frames) if inp.rotate_light else run_light.rotation_deg for i in range(len(frames))]
    record = light_record(inp.light, inp.light_file, asset.light, frames, rotations)
    cameras = spread(inp.capture.cameras, settings.views)
    with reporter.stage("render_frames", total=len(frames) * len(cameras)) as st:
        for i, t in enumerate(frames):
            frame_light = replace(run_light, rotation_deg=rotations[i])
            body = Mesh(body_vertices[t], body_faces, name="body")
            per_cam = [renderer.frame(vertices[t].astype(np.float64), cam, frame_light, kernel, body)
                       for cam in cameras]
            save_npz(folder / f"frame_{t:04d}.npz", **{k: np.stack([p[k] for p in per_cam]) for k in per_cam[0]})
            st.progress((i + 1) * len(cameras))
    meta_out = {"frames": frames, "cameras": [c.name for c in cameras], **kernel.to_json(),
                "inputs": render_inputs(run_dir),
                "light": {"radiance": run_light.radiance.tolist(), "envmap": run_light.envmap is not None,
                          "rotating": inp.rotate_light, **record}}
    write_json(folder / "render.json", meta_out)
    return meta_out, {"kernel_size": kernel.kernel_size, "frames": len(frames), "views": len(cameras)}


def load_render(ctx: StageContext[RenderInputs], folder: Path) -> None:
    """The frames stay on disk (``pgc eval`` reads them); nothing is loaded."""
    return None


STAGES = ((render_stage.STAGE, Step(compute_render, load_render)),)
"""The stages of ``pgc render``, each with its code."""


def render_run(run_dir: str | Path, cfg: RunConfig, light: Light | None = None,
               reporter: Reporter | None = None, rotate_light: bool = False,
               decide: Callable[[HybridRenderer, Capture], KernelDecision] | None = None,
               light_file: str | Path | None = None) -> Path:
    """Render the run's frames (every ``frame_stride``-th) from ``views`` capture cameras under ``light`` (the
    asset's fitted light by default); with ``rotate_light`` the environment turns 360 degrees about +Y over the
    rendered frames. ``decide(renderer, capture)`` gives the kernel rule's decision (default :func:`choose_kernel`
    with ``cfg``); it is called only when the stage is computed, so ``pgc demo`` passes one that decides once for
    all motions of its asset. ``light_file``: the environment map file ``light`` was read from, recorded in
    ``render.json`` (name, path, sha256, rotation per frame) so that ``pgc eval`` renders the truth under it."""
    from pgc.io.asset import read_asset
    from pgc.io.capture import read_capture

    run_dir = Path(run_dir)
    meta = read_run(run_dir)
    asset = read_asset(meta["asset"])
    capture = read_capture(meta["capture"]) if meta.get("capture") else None
    if capture is None:
        raise PGCDataError(f"{run_dir}: the run records no capture; its cameras are needed to render")
    run_light = light or asset.light
    source = light_record(light, light_file, asset.light, [], [])
    inputs = RenderInputs(run_dir, asset, capture, HybridRenderer(asset, cfg), light, light_file, rotate_light, decide)
    cache = StageCache(run_dir)
    runner = StageRunner(cache, StageContext(cfg, reporter or Reporter.silent(), inputs), {
        "run": file_key(run_dir / "garment.npz"), "asset": asset_key(meta["asset"]),
        # the light file's name, path and sha256 are part of the key
        "light": {"radiance": run_light.radiance.tolist(), "rotation": run_light.rotation_deg,
                  "envmap": None if run_light.envmap is None else array_key(run_light.envmap),
                  "rotating": rotate_light,
                  "file": None if source["kind"] == "capture" else {k: source.get(k)
                                                                   for k in ("kind", "file", "path", "sha256")}}})
    for stage, step in STAGES:
        runner.run(stage, step)
    return cache.folder("render")
