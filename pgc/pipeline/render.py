"""``pgc render``: hybrid rendering of an animated run (METHOD.md section 5), with its ablations.

Per rendered frame and camera: the near field ``G_t`` (the optimised Gaussians on the simulated garment),
the far field ``S_t`` (the Gaussians coloured by the PBR renderer's texture-space radiance ``T_t``), the
hybrid ``h(G_t) + l(S_t)``, and the PBR-only ablation (the mesh rendered by the PBR renderer). The low-pass
kernel is chosen once on the training frame (the capture pose) by the configured rule.
Output: ``RUN/render/frame_XXXX.npz`` (arrays stacked over cameras) and ``RUN/render/render.json``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pgc.config import RunConfig
from pgc.events import Reporter
from pgc.geometry.raster import rasterize
from pgc.io.atomic import write_json
from pgc.pipeline.animate import read_run
from pgc.pipeline.cache import StageCache, array_key, content_key, file_key
from pgc.pipeline.compose import (compose, far_field_gaussians, gaussian_uvs, hide_behind, unpremultiply,
                                  visible_surface_uvs)
from pgc.pipeline.garment import body_occluder
from pgc.pipeline.stage_io import save_npz
from pgc.splats.binding import bind
from pgc.types import Camera, GarmentAsset, Light, Mesh


def spread(items: list, count: int) -> list:
    """``count`` items evenly spread over ``items`` (all when there are fewer)."""
    if count >= len(items):
        return list(items)
    return [items[int(i)] for i in np.linspace(0, len(items) - 1, count).round().astype(int)]


class HybridRenderer:
    """Renders one garment state from one camera with the configured splat renderer, PBR renderer and filter."""

    def __init__(self, asset: GarmentAsset, cfg: RunConfig, light: Light | None = None) -> None:
        self.asset = asset
        self.splats = cfg.create("splat_renderer")
        self.pbr = cfg.create("pbr_renderer")
        self.filter = cfg.create("filter")
        self.settings = cfg.stage("render")
        self.light = light or asset.light
        self.uvs = gaussian_uvs(asset.gaussians, asset.garment)
        self.far_source = "splats" if self.settings.far_source == "auto" else self.settings.far_source
        """The far field in use; 'auto' is resolved by :func:`choose_kernel`."""

    def mesh_at(self, vertices: np.ndarray) -> Mesh:
        g = self.asset.garment
        return Mesh(vertices, g.faces, g.uv, g.face_uv, g.face_labels, name="garment")

    def layers(self, vertices: np.ndarray, camera: Camera, occluder: Mesh | None = None) -> dict[str, Any]:
        """Near-field, far-field and PBR-only renders of the garment at ``vertices`` (before composition);
        ``occluder`` (the body in the same frame) shadows the far field and, with ``body_occludes``, hides
        the garment where it is in front."""
        mesh = self.mesh_at(vertices)
        faces = self.asset.garment.faces
        world = bind(self.asset.gaussians, vertices, faces)
        near = self.splats.render(world, camera)
        raster = rasterize(camera, vertices, faces)
        hides = occluder if self.settings.body_occludes else None
        pbr = self.pbr.render(mesh, self.asset.material, self.light, camera, occluder=hides)
        far = pbr
        if self.far_source == "splats":
            size = self.settings.texture_size
            texture, _ = self.pbr.render_texture(mesh, self.asset.material, self.light, camera, (size, size),
                                                 occluder=occluder)
            uvs = self.uvs
            if self.settings.far_lookup == "visible":
                uvs = visible_surface_uvs(world.means, raster, mesh, camera, self.uvs)
            far = self.splats.render(bind(far_field_gaussians(self.asset.gaussians, uvs, texture), vertices, faces),
                                     camera)
        if hides is not None:  # the garment's first surface decides; beyond its silhouette, the splats' depth
            depth = np.where(np.isfinite(raster.depth), raster.depth, near.depth)
            body_depth = rasterize(camera, hides.vertices, hides.faces).depth
            near = hide_behind(near, body_depth, depth)
            if far is not pbr:
                far = hide_behind(far, body_depth, depth)
        return {"near": near, "far": far, "pbr": pbr}

    def frame(self, vertices: np.ndarray, camera: Camera, kernel_size: int,
              occluder: Mesh | None = None) -> dict[str, np.ndarray]:
        lay = self.layers(vertices, camera, occluder)
        h = compose(lay["near"], lay["far"], self.filter, kernel_size, silhouette=self.settings.silhouette)
        return {"hybrid": h.hybrid, "near": h.near, "far": h.far, "pbr": lay["pbr"].color,
                "alpha": h.alpha, "hybrid_alpha": h.hybrid_alpha, "pbr_alpha": lay["pbr"].alpha,
                "low_far": h.low_far, "high_near": h.high_near}


def kernel_views(asset: GarmentAsset, capture, count: int) -> list:
    """Up to ``count`` capture views for the kernel rule: those the splat fit held out when it recorded them
    (on views it trained on, the near field's error is optimistic and pulls toward large kernels), else any."""
    held = set(asset.figures.get("splats", {}).get("heldout_views", []))
    pool = [v for v in capture.views if v.camera.name in held] or capture.views
    return spread(pool, count)


def choose_kernel(renderer: HybridRenderer, capture, cfg: RunConfig) -> dict[str, Any]:
    """Apply the configured kernel rule to the training frame (capture pose, lit by the asset's fitted capture
    light whatever light the run is rendered under) on the kernel views; with ``far_source = 'auto'`` also
    choose the far field (and set it on ``renderer``)."""
    run_light, renderer.light = renderer.light, renderer.asset.light
    try:
        return _choose_kernel(renderer, capture, cfg)
    finally:
        renderer.light = run_light


def _choose_kernel(renderer: HybridRenderer, capture, cfg: RunConfig) -> dict[str, Any]:
    from pgc.albedo.texture_stage import garment_mask
    from pgc.filtering.auto import hybrid_error, select_kernel

    settings = cfg.stage("render")
    sources = ("splats", "mesh") if settings.far_source == "auto" else (settings.far_source,)
    renderer.far_source = sources[0]  # 'splats' renders the mesh image too: one pass serves both
    rest = renderer.asset.garment.vertices
    body = body_occluder(renderer.asset.body, capture.garment_label_ids)
    views = kernel_views(renderer.asset, capture, settings.kernel_views)
    per_view = []
    for view in views:
        lay = renderer.layers(rest, view.camera, body)
        far = {"splats": lay["far"], "mesh": lay["pbr"]} if len(sources) > 1 else {sources[0]: lay["far"]}
        near = unpremultiply(lay["near"])
        mask = garment_mask(view, capture.garment_label_ids)
        per_view.append((view, near, lay["near"].alpha, {k: (unpremultiply(f), f.alpha) for k, f in far.items()},
                         mask))
    result: dict[str, Any] = {}
    for source in sources:
        choices = [select_kernel(settings.kernel, renderer.filter, v.image, a, g, *far[source], m)
                   for v, g, a, far, m in per_view]
        size = int(np.median([c.size for c in choices])) | 1
        error = float(np.mean([hybrid_error(renderer.filter, v.image, g, a, *far[source], m, size)
                               for v, g, a, far, m in per_view]))
        result[source] = {"kernel_size": size, "criterion": choices[0].criterion,
                          "per_view": [c.size for c in choices], "error": error}
    chosen = min(result, key=lambda k: result[k]["error"])
    renderer.far_source = chosen
    return {**{k: v for k, v in result[chosen].items() if k != "error"}, "far_source": chosen,
            "far_errors": {k: v["error"] for k, v in result.items()},
            "kernel_views": [v.camera.name for v in views]}


_KERNEL_CHOICES: dict[str, dict[str, Any]] = {}
"""Kernel rule results of this process by content key (asset, capture, render settings, roles): the rule
depends on none of a run's own data, so ``pgc demo`` rendering three motions of one asset runs it once."""


def envmap_light(run_dir: str | Path, path: str | Path) -> Light:
    """An environment-map light (EXR, latitude-longitude, +Y up) scaled by the asset's fitted radiance."""
    from pgc.io.asset import read_asset
    from pgc.io.images import read_exr

    asset = read_asset(read_run(run_dir)["asset"])
    return Light(asset.light.radiance, envmap=read_exr(path))


def render_run(run_dir: str | Path, cfg: RunConfig, light: Light | None = None,
               reporter: Reporter | None = None, rotate_light: bool = False) -> Path:
    """Render the run's frames (every ``frame_stride``-th) from ``views`` capture cameras; with
    ``rotate_light`` the environment turns 360 degrees about +Y over the rendered frames."""
    from pgc.io.asset import read_asset
    from pgc.io.capture import read_capture

    reporter = reporter or Reporter.silent()
    run_dir = Path(run_dir)
    meta = read_run(run_dir)
    asset = read_asset(meta["asset"])
    capture = read_capture(meta["capture"]) if meta.get("capture") else None
    if capture is None:
        from pgc.errors import PGCDataError

        raise PGCDataError(f"{run_dir}: the run records no capture; its cameras are needed to render")
    settings = cfg.stage("render")
    renderer = HybridRenderer(asset, cfg, light)
    key = content_key("render", file_key(run_dir / "garment.npz"), file_key(Path(meta["asset"]) / "manifest.json"),
                      settings, rotate_light, [cfg.role_key(r) for r in ("splat_renderer", "pbr_renderer", "filter")],
                      {"radiance": renderer.light.radiance.tolist(), "rotation": renderer.light.rotation_deg,
                       "envmap": None if renderer.light.envmap is None else array_key(renderer.light.envmap)})

    def compute(folder: Path):
        kernel_key = content_key("kernel", file_key(Path(meta["asset"]) / "manifest.json"), file_key(meta["capture"]),
                                 settings.model_dump(exclude={"views", "frame_stride"}),
                                 [cfg.role_key(r) for r in ("splat_renderer", "pbr_renderer", "filter")])
        with reporter.stage("choose_kernel") as st:
            if kernel_key not in _KERNEL_CHOICES:
                _KERNEL_CHOICES[kernel_key] = choose_kernel(renderer, capture, cfg)
            kernel = _KERNEL_CHOICES[kernel_key]
            renderer.far_source = kernel["far_source"]
            st.record(kernel_size=kernel["kernel_size"], far_source=kernel["far_source"])
        vertices = np.load(run_dir / "garment.npz")["vertices"]
        with np.load(run_dir / "body.npz") as z:
            body_vertices, body_faces = z["vertices"], z["faces"]
        frames = list(range(0, len(vertices), settings.frame_stride))
        cameras = spread(capture.cameras, settings.views)
        with reporter.stage("render_frames", total=len(frames) * len(cameras)) as st:
            for i, t in enumerate(frames):
                if rotate_light:
                    renderer.light = replace(renderer.light, rotation_deg=360.0 * i / len(frames))
                body = Mesh(body_vertices[t], body_faces, name="body")
                per_cam = [renderer.frame(vertices[t].astype(np.float64), cam, kernel["kernel_size"], body)
                           for cam in cameras]
                save_npz(folder / f"frame_{t:04d}.npz", **{k: np.stack([p[k] for p in per_cam]) for k in per_cam[0]})
                st.progress((i + 1) * len(cameras))
        meta_out = {"frames": frames, "cameras": [c.name for c in cameras], **kernel,
                    "light": {"radiance": renderer.light.radiance.tolist(), "envmap": renderer.light.envmap is not None,
                              "rotating": rotate_light}}
        write_json(folder / "render.json", meta_out)
        return meta_out, {"kernel_size": kernel["kernel_size"], "frames": len(frames), "views": len(cameras)}

    return StageCache(run_dir).run("render", key, compute, lambda f: None).folder
