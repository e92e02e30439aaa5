"""``pgc reconstruct``: capture -> garment asset, every stage cached by content hash and resumable.

Stages (declared in :mod:`pgc.stages`; folder ``OUT/stages/<name>``, options ``[stages.<name>]``): ``mesh``
(reconstructor: labelled full-body mesh with UVs) -> ``garment`` (the garment sub-mesh with its own UV atlas) ->
``fit_splats`` (mesh-embedded Gaussians fitted on the full mesh, then only the garment's kept) -> ``base_color``
(albedo estimator + colour correction + UV merge on the garment) -> ``material`` (BRDF parameters and the
light's radiance, fitted by the PBR renderer under the capture's light) -> ``body_fit`` (the body model fitted to
the capture's labels, when the asset's garment moves on it: :func:`pgc.pipeline.motion_source.motion_body`; copied
to ``OUT/body_fit``) -> the asset directory ``OUT``, whose config records that body (``source.body``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pgc.config import RunConfig
from pgc.events import Reporter
from pgc.geometry.garment import garment_selection
from pgc.io.atomic import write_json
from pgc.io.body_fit import BODY_FIT_DIR
from pgc.io.limits import read_json
from pgc.pipeline.cache import StageCache, file_key
from pgc.pipeline.garment import body_occluder, garment_gaussians, with_occluder
from pgc.pipeline.motion_source import motion_body
from pgc.pipeline.runner import StageContext, StageRunner, Step
from pgc.pipeline.stage_io import load_gaussians, load_mesh, save_gaussians, save_mesh
from pgc.stages import base_color, body_fit, fit_splats, garment, material, mesh
from pgc.stages.garment import GarmentSettings
from pgc.types import Capture, GarmentAsset, Light, Material, Mesh


@dataclass(frozen=True)
class ReconstructInputs:
    capture: Capture


Context = StageContext[ReconstructInputs]


def extract_garment(full: Mesh, garment_ids: list[int], settings: GarmentSettings) -> tuple[Mesh, np.ndarray]:
    """The garment faces of ``full`` as one clean piece with its own UV atlas (xatlas); without pymeshlab and
    xatlas, the full mesh's atlas restricted to those faces."""
    from pgc.registry import module_available

    if module_available("pymeshlab") and module_available("xatlas"):
        from pgc.geometry.finish import extract_garment as extract

        return extract(full, garment_ids, settings.min_island_faces, settings.uv_resolution, settings.uv_padding)
    sel = garment_selection(full, garment_ids, settings.min_island_faces)
    return full.submesh(sel, name="garment")[0], sel


def compute_mesh(ctx: Context, folder: Path) -> tuple[Mesh, dict[str, Any]]:
    rec = ctx.cfg.create("reconstructor").reconstruct(ctx.inputs.capture, ctx.reporter)
    save_mesh(folder / "mesh.npz", rec.mesh)
    return rec.mesh, rec.figures


def load_full_mesh(ctx: Context, folder: Path) -> Mesh:
    return load_mesh(folder / "mesh.npz")


def compute_garment(ctx: Context, folder: Path) -> tuple[tuple[Mesh, np.ndarray], dict[str, Any]]:
    """The garment sub-mesh with its own UV atlas (the simulator's rest shape and the texture's domain)."""
    piece, sel = extract_garment(ctx.values["mesh"], ctx.inputs.capture.garment_label_ids, ctx.cfg.stage("garment"))
    save_mesh(folder / "garment.npz", piece)
    np.save(folder / "selection.npy", sel)
    return (piece, sel), {"garment_vertices": len(piece.vertices), "garment_faces": len(piece.faces)}


def load_garment(ctx: Context, folder: Path) -> tuple[Mesh, np.ndarray]:
    return load_mesh(folder / "garment.npz"), np.load(folder / "selection.npy")


def compute_splats(ctx: Context, folder: Path) -> tuple[tuple[Any, list[str]], dict[str, Any]]:
    fit = ctx.cfg.create("splat_renderer").fit(ctx.inputs.capture, ctx.values["mesh"], ctx.cfg.stage("fit_splats"),
                                             ctx.reporter)
    save_gaussians(folder / "gaussians_full.npz", fit.gaussians)
    write_json(folder / "heldout_views.json", fit.heldout_views)
    return (fit.gaussians, fit.heldout_views), fit.figures


def load_splats(ctx: Context, folder: Path) -> tuple[Any, list[str]]:
    return load_gaussians(folder / "gaussians_full.npz"), read_json(folder / "heldout_views.json")


def compute_base_color(ctx: Context, folder: Path) -> tuple[np.ndarray, dict[str, Any]]:
    from pgc.albedo.base_color import build_base_color

    settings, full = ctx.cfg.stage("base_color"), ctx.values["mesh"]
    estimator = ctx.implementation("albedo_estimator")
    shading = white_shading(ctx.cfg, full, ctx.inputs.capture.light) \
        if getattr(estimator, "needs_shading", False) else None
    res = build_base_color(ctx.inputs.capture, ctx.values["garment"][0], estimator, settings.texture_size,
                           settings.num_views, occluder=full, shading=shading, reporter=ctx.reporter)
    np.save(folder / "base_color.npy", res.texture)
    return res.texture, res.figures


def load_base_color(ctx: Context, folder: Path) -> np.ndarray:
    return np.load(folder / "base_color.npy")


def compute_material(ctx: Context, folder: Path) -> tuple[tuple[Material, Light], dict[str, Any]]:
    """The BRDF's parameters and the light's radiance, fitted by the PBR renderer under the capture's light."""
    from pgc.io import images as imgio
    from pgc.io.timings import split_timings

    capture, full, piece = ctx.inputs.capture, ctx.values["mesh"], ctx.values["garment"][0]
    renderer = ctx.cfg.create("pbr_renderer")
    init = Material(ctx.cfg.roles["brdf"].name, ctx.cfg.create("brdf").initial_params(), ctx.values["base_color"])
    # the body casts shadows on the garment: the renderer splits it off by label
    scene = with_occluder(piece, body_occluder(full, capture.garment_label_ids))
    fit = renderer.fit(capture, scene, init, ctx.cfg.stage("material"), ctx.reporter)
    light: dict[str, Any] = {"radiance": fit.light.radiance.tolist(), "rotation_deg": float(fit.light.rotation_deg),
                             "envmap": None}
    if fit.light.envmap is not None:
        light["envmap"] = "light_envmap.exr"
        imgio.write_exr(folder / light["envmap"], fit.light.envmap)
    write_json(folder / "material.json",  # the fit's seconds stay in stage.json: the same bytes every run
               {"brdf": fit.material.brdf, "params": fit.material.params, "light": light,
                "figures": split_timings(fit.figures)[0]})
    return (fit.material, fit.light), fit.figures


def load_material(ctx: Context, folder: Path) -> tuple[Material, Light]:
    from pgc.io import images as imgio

    d = read_json(folder / "material.json")
    light = d["light"]
    envmap = imgio.read_envmap(folder / light["envmap"]) if light.get("envmap") else None
    return (Material(d["brdf"], d["params"], ctx.values["base_color"]),
            Light(np.asarray(light["radiance"]), envmap, float(light.get("rotation_deg", 0.0))))


def compute_body_fit(ctx: Context, folder: Path) -> tuple[Any, dict[str, Any]]:
    """The body model fitted to the capture (:func:`pgc.body.fit.fit_body`), written as body.json and body.ply."""
    from pgc.body.fit import fit_body
    from pgc.io.body_fit import write_body_fit
    from pgc.io.keypoints import read_keypoints

    capture = ctx.inputs.capture
    keypoints = read_keypoints(capture.root, [v.camera.name for v in capture.views]) if capture.root else None
    fit = fit_body(capture, ctx.implementation("body_model"), ctx.cfg.stage("body_fit"),
                   ctx.cfg.roles["body_model"].name, keypoints, ctx.reporter, where=capture.root or "capture")
    write_body_fit(folder, fit)
    return fit, {k: v for k, v in fit.figures.items() if k != "view_names"}


def load_body_fit(ctx: Context, folder: Path) -> Any:
    from pgc.io.body_fit import read_body_fit

    return read_body_fit(folder)


STAGES = ((mesh.STAGE, Step(compute_mesh, load_full_mesh)),
          (garment.STAGE, Step(compute_garment, load_garment)),
          (fit_splats.STAGE, Step(compute_splats, load_splats)),
          (base_color.STAGE, Step(compute_base_color, load_base_color)),
          (material.STAGE, Step(compute_material, load_material)),
          (body_fit.STAGE, Step(compute_body_fit, load_body_fit)))
"""The stages of ``pgc reconstruct``, in order, each with its code."""


def reconstruct(capture_dir: str | Path, out: str | Path, cfg: RunConfig,
                reporter: Reporter | None = None) -> GarmentAsset:
    """Run every stage (reusing cached ones) and write the asset to ``out``: its garment moves on the body that
    :func:`~pgc.pipeline.motion_source.motion_body` chooses for ``[stages.body_fit] motion_body``."""
    from pgc.io.asset import write_asset
    from pgc.io.capture import read_capture
    from pgc.io.timings import write_timings

    from pgc.io.capture_checks import require_segmentation

    out = Path(out)
    capture = read_capture(capture_dir)
    require_segmentation(capture, str(Path(capture_dir) / "transforms.json"), "reconstruction")
    ctx = StageContext(cfg, reporter or Reporter.silent(), ReconstructInputs(capture))
    runner = StageRunner(StageCache(out / "stages"), ctx, {"capture": file_key(capture_dir),
                                                           "garment_labels": capture.garment_label_ids})
    body = motion_body(capture_dir, cfg.stage("body_fit").motion_body)
    for stage, step in STAGES:
        if stage is body_fit.STAGE and body == "truth":
            continue  # the capture's true body drives the motions
        runner.run(stage, step)
    full, (piece, sel) = ctx.values["mesh"], ctx.values["garment"]
    full_gaussians, heldout_views = ctx.values["fit_splats"]
    mat, light = ctx.values["material"]
    mat.base_color = ctx.values["base_color"]
    figures, stage_timings = runner.figures()
    gaussians = garment_gaussians(full_gaussians, sel)
    figures["gaussians_garment"] = len(gaussians)
    asset = GarmentAsset(garment=piece, body=full, gaussians=gaussians, material=mat, light=light,
                         heldout_views=heldout_views,
                         config=dict(cfg.to_dict(), source={"capture": str(Path(capture_dir).resolve()), "body": body}),
                         figures=figures)
    write_asset(out, asset)
    if body == "fit":
        from pgc.io.body_fit import write_body_fit

        write_body_fit(out / BODY_FIT_DIR, ctx.values["body_fit"])
    elif (out / BODY_FIT_DIR).is_dir():  # an earlier reconstruction's: this asset moves on the true body
        import shutil

        shutil.rmtree(out / BODY_FIT_DIR)
    write_timings(out, {"seconds": runner.seconds, "stages": stage_timings or {}})
    return asset


def white_shading(cfg: RunConfig, mesh: Mesh, capture_light: Light | None = None):
    """A function giving the white-albedo shading of ``mesh`` in a view under the capture's light shape at unit
    radiance (its environment map and rotation; a constant where the capture records none)."""
    renderer = cfg.create("pbr_renderer")
    white = Material("lambertian", {}, None)
    white.params["base_color"] = [1.0, 1.0, 1.0]
    light = Light(np.ones(3)) if capture_light is None else Light(np.ones(3), capture_light.envmap,
                                                                  capture_light.rotation_deg)

    def shade(view):
        return renderer.render(mesh, white, light, view.camera).color

    return shade

