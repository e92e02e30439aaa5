"""``pgc reconstruct``: capture -> garment asset, every stage cached by content hash and resumable.

Stages (folder ``OUT/stages/<name>``, options ``[stages.<name>]``): ``mesh`` (reconstructor: labelled full-body
mesh with UVs) -> ``garment`` (the garment sub-mesh with its own UV atlas) -> ``fit_splats`` (mesh-embedded
Gaussians fitted on the full mesh, then only the garment's kept) ->
``base_color`` (albedo estimator + colour correction + UV merge on the garment) -> ``material``
(BRDF parameters and the constant light, fitted by the PBR renderer) -> the asset directory ``OUT``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from pgc.config import RunConfig
from pgc.events import Reporter
from pgc.geometry.garment import garment_selection
from pgc.io.atomic import write_json
from pgc.io.limits import read_json
from pgc.pipeline.cache import StageCache, content_key, file_key
from pgc.pipeline.garment import body_occluder, garment_gaussians, with_occluder
from pgc.pipeline.settings_garment import GarmentSettings
from pgc.pipeline.stage_io import load_gaussians, load_mesh, save_gaussians, save_mesh
from pgc.types import GarmentAsset, Light, Material, Mesh

CODE_VERSIONS = {"mesh": "3", "garment": "2", "fit_splats": "3", "base_color": "2", "material": "3"}
"""Version of the code computing each stage, part of its cache key: raise one when that stage's code changes
what it computes, so no run reuses a result made by older code."""


def extract_garment(full: Mesh, garment_ids: list[int], settings: GarmentSettings) -> tuple[Mesh, np.ndarray]:
    """The garment faces of ``full`` as one clean piece with its own UV atlas (xatlas); without pymeshlab and
    xatlas, the full mesh's atlas restricted to those faces."""
    from pgc.registry import module_available

    if module_available("pymeshlab") and module_available("xatlas"):
        from pgc.geometry.finish import extract_garment as extract

        return extract(full, garment_ids, settings.min_island_faces, settings.uv_resolution, settings.uv_padding)
    sel = garment_selection(full, garment_ids, settings.min_island_faces)
    return full.submesh(sel, name="garment")[0], sel


def reconstruct(capture_dir: str | Path, out: str | Path, cfg: RunConfig,
                reporter: Reporter | None = None) -> GarmentAsset:
    """Run every stage (reusing cached ones) and write the asset to ``out``."""
    from pgc.io.asset import write_asset
    from pgc.io.capture import read_capture
    from pgc.io.timings import split_timings, write_timings

    reporter = reporter or Reporter.silent()
    out = Path(out)
    cache = StageCache(out / "stages")
    capture = read_capture(capture_dir)
    capture_key = file_key(capture_dir)
    timings: dict[str, float] = {}

    def timed(name: str, fn):
        start = time.perf_counter()
        result = fn()
        timings[name] = timings.get(name, 0.0) + (0.0 if result.cached else time.perf_counter() - start)
        return result

    # 1. mesh
    mesh_key = content_key("mesh", capture_key, cfg.role_key("reconstructor"))

    def compute_mesh(folder: Path):
        rec = cfg.create("reconstructor").reconstruct(capture, reporter)
        save_mesh(folder / "mesh.npz", rec.mesh)
        return rec.mesh, rec.figures

    full = timed("mesh", lambda: cache.run("mesh", mesh_key, compute_mesh, lambda f: load_mesh(f / "mesh.npz"),
                                           CODE_VERSIONS["mesh"]))
    # 2. the garment sub-mesh with its own UV atlas (the simulator's rest shape and the texture's domain)
    garment_settings = cfg.stage("garment")
    garment_key = content_key("garment", cache.output_key("mesh"), garment_settings, capture.garment_label_ids)

    def compute_garment(folder: Path):
        garment, sel = extract_garment(full.value, capture.garment_label_ids, garment_settings)
        save_mesh(folder / "garment.npz", garment)
        np.save(folder / "selection.npy", sel)
        return (garment, sel), {"garment_vertices": len(garment.vertices), "garment_faces": len(garment.faces)}

    def load_garment(folder: Path):
        return load_mesh(folder / "garment.npz"), np.load(folder / "selection.npy")

    garment, sel = timed("garment", lambda: cache.run("garment", garment_key, compute_garment, load_garment,
                                                      CODE_VERSIONS["garment"])).value

    # 3. the splat fit
    splat_settings = cfg.stage("fit_splats")
    splat_key = content_key("fit_splats", capture_key, cache.output_key("mesh"), cfg.role_key("splat_renderer"),
                            splat_settings)

    def compute_splats(folder: Path):
        fit = cfg.create("splat_renderer").fit(capture, full.value, splat_settings, reporter)
        save_gaussians(folder / "gaussians_full.npz", fit.gaussians)
        write_json(folder / "heldout_views.json", fit.heldout_views)
        return (fit.gaussians, fit.heldout_views), fit.figures

    def load_splats(folder: Path):
        return load_gaussians(folder / "gaussians_full.npz"), read_json(folder / "heldout_views.json")

    full_gaussians, heldout_views = timed("fit_splats", lambda: cache.run(
        "fit_splats", splat_key, compute_splats, load_splats, CODE_VERSIONS["fit_splats"])).value
    gaussians = garment_gaussians(full_gaussians, sel)

    # 4. base colour
    tex_settings = cfg.stage("base_color")
    estimator = cfg.create("albedo_estimator")
    from pgc.albedo.texture_stage import STAGE_VERSION

    tex_key = content_key("base_color", STAGE_VERSION, capture_key, cache.output_key("mesh"),
                          cache.output_key("garment"), cfg.role_key("albedo_estimator"), estimator.fingerprint,
                          tex_settings)

    def compute_texture(folder: Path):
        from pgc.albedo.texture_stage import build_base_color

        shading = white_shading(cfg, full.value) if getattr(estimator, "needs_shading", False) else None
        res = build_base_color(capture, garment, estimator, tex_settings.texture_size, tex_settings.num_views,
                               occluder=full.value, shading=shading, reporter=reporter)
        np.save(folder / "base_color.npy", res.texture)
        return res.texture, res.figures

    texture = timed("base_color", lambda: cache.run("base_color", tex_key, compute_texture,
                                                    lambda f: np.load(f / "base_color.npy"),
                                                    CODE_VERSIONS["base_color"]))

    # 5. material and light
    mat_settings = cfg.stage("material")
    mat_key = content_key("material", capture_key, cache.output_key("mesh"), cache.output_key("garment"),
                          cache.output_key("base_color"), cfg.role_key("pbr_renderer"), cfg.role_key("brdf"),
                          mat_settings)

    def compute_material(folder: Path):
        renderer = cfg.create("pbr_renderer")
        init = Material(cfg.roles["brdf"].name, cfg.create("brdf").initial_params(), texture.value)
        # the body casts shadows on the garment: the renderer splits it off by label
        scene = with_occluder(garment, body_occluder(full.value, capture.garment_label_ids))
        fit = renderer.fit(capture, scene, init, mat_settings, reporter)
        write_json(folder / "material.json",  # the fit's seconds stay in stage.json: the same bytes every run
                   {"brdf": fit.material.brdf, "params": fit.material.params,
                    "light": {"radiance": fit.light.radiance.tolist()}, "figures": split_timings(fit.figures)[0]})
        return (fit.material, fit.light), fit.figures

    def load_material(folder: Path):
        d = read_json(folder / "material.json")
        return Material(d["brdf"], d["params"], texture.value), Light(np.asarray(d["light"]["radiance"]))

    material = timed("material", lambda: cache.run("material", mat_key, compute_material, load_material,
                                                   CODE_VERSIONS["material"]))
    mat, light = material.value
    mat.base_color = texture.value

    figures, stage_timings = split_timings({name: cache.figures(name) for name in CODE_VERSIONS})
    figures["gaussians_garment"] = len(gaussians)
    asset = GarmentAsset(garment=garment, body=full.value, gaussians=gaussians, material=mat, light=light,
                         heldout_views=heldout_views,
                         config=dict(cfg.to_dict(), source={"capture": str(Path(capture_dir).resolve())}),
                         figures=figures)
    write_asset(out, asset)
    write_timings(out, {"seconds": timings, "stages": stage_timings or {}})
    return asset


def white_shading(cfg: RunConfig, mesh: Mesh):
    """A function giving the white-albedo shading of ``mesh`` in a view (unit constant light)."""
    renderer = cfg.create("pbr_renderer")
    white = Material("lambertian", {}, None)
    white.params["base_color"] = [1.0, 1.0, 1.0]

    def shade(view):
        return renderer.render(mesh, white, Light(np.ones(3)), view.camera).color

    return shade

