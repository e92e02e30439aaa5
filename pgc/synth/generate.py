"""``pgc synth``: the whole synthetic capture, from body to files on disk.

body -> garment -> fabric (textures, normal map, fibres) -> dome cameras -> per view: path-traced colour
(8-bit sRGB PNG, and the float linear image as the extra layer 'linear'), ray-cast mask / segmentation /
albedo / depth, empty-dome background -> capture folder (written with
:func:`pgc.io.capture.write_capture`) + ``ground_truth/`` + ``contact_sheet.png``.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.types import Camera, Capture, Mesh, View

if TYPE_CHECKING:
    from pgc.synth.body import SynthBody
    from pgc.synth.ground_truth import GroundTruth
    from pgc.roles.body_model import BodyModel
    from pgc.roles.scene_renderer import SceneRenderer


@dataclass(frozen=True)
class SynthPreset:
    """Sizes and sample counts of a synthetic capture."""

    views: int
    resolution: int
    """Image width and height, pixels."""
    garment_edge: float
    """Garment mesh edge length, metres."""
    texture: int
    """Texture size, texels square."""
    spp: int
    """Path-tracing samples per pixel (see docs/synth.md for the noise measurement behind it)."""
    gt_samples: int
    """Sub-pixel rays per axis for the ground-truth layers (mask coverage resolution 1 / gt_samples^2)."""
    fibre_scale: float
    """Multiplier of the fabric's fibre density."""
    envmap_height: int = 64
    sampler: str = "ldsampler"
    """Mitsuba sampler: the low-discrepancy sampler halves the noise of 'independent' at equal spp
    (benchmarks/bench_synth.py); its spp must be a power of 4."""
    garment: str = "tshirt"
    """Garment kind (:data:`pgc.synth.garments` names: tshirt, dress)."""
    fabric: str = "cotton-sheen"
    """Fabric preset (:data:`pgc.synth.fabrics.FABRICS`): the demo's ``default`` preset takes the cotton fibre
    truth; the others keep the pgc-sheen cotton (an in-family control), as a fibre truth costs 2.7-4.9 times its
    render time (docs/synth.md, "Fibre truths")."""
    framing: str = "body"
    """'body': the whole body fills the views; 'garment': the same dome cameras zoom onto the garment (its
    bounding sphere times ``GARMENT_FRAME_MARGIN``, room for the motions), so its fabric takes the pixels."""
    detail: str = "none"
    """Near-field detail (:data:`pgc.synth.detail.DETAILS`): 'none', 'relief' (knit ribs, ribbed bands,
    seams, a patch pocket, folds as real geometry embedded in the garment) or 'seams' (the same without the
    knit ribs)."""
    fit: str = "loose"
    """Garment fit (:data:`pgc.synth.garments.FITS`): 'loose' or 'resting' (hangs from the shoulders)."""
    looseness: float = 0.03
    """Garment clearance from the body, metres ('resting': at the waist and below)."""
    capture_light: str = "uniform"
    """The dome's light (:data:`pgc.synth.rig.CAPTURE_LIGHTS`: 'uniform' or 'sky-sun'), recorded in the
    capture (transforms.json ``pgc_light``, ground_truth/light.json) for the material fit."""


PRESETS: dict[str, SynthPreset] = {
    "tiny": SynthPreset(views=6, resolution=64, garment_edge=0.04, texture=256, spp=16,
                        gt_samples=2, fibre_scale=0.3, envmap_height=16),
    "default": SynthPreset(views=128, resolution=192, garment_edge=0.02, texture=1024, spp=64,
                           gt_samples=4, fibre_scale=1.0, fabric="cotton", framing="garment", detail="seams",
                           fit="resting", looseness=0.012),
    "cotton": SynthPreset(views=128, resolution=256, garment_edge=0.02, texture=1024, spp=64,
                          gt_samples=4, fibre_scale=1.0),
    "large": SynthPreset(views=64, resolution=1024, garment_edge=0.012, texture=2048, spp=64,
                         gt_samples=4, fibre_scale=2.0, envmap_height=256),
    "knit": SynthPreset(views=32, resolution=320, garment_edge=0.02, texture=1024, spp=64,
                        gt_samples=4, fibre_scale=20.0, fabric="rib-knit-sheen", framing="garment", detail="relief",
                        fit="resting", looseness=0.012),
}


def get_preset(name: str, **overrides) -> SynthPreset:
    if name not in PRESETS:
        raise PGCDataError(f"unknown synth preset '{name}'; presets: {', '.join(PRESETS)}")
    return replace(PRESETS[name], **{k: v for k, v in overrides.items() if v is not None})


GARMENT_FRAME_MARGIN = 1.15
"""Garment framing: the bounding sphere's radius times this (sleeves and hem move in the test motions)."""


def framing_sphere(framing: str, height: float, garment_vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """The sphere (centre, radius; metres) the dome cameras frame: the body (``height`` tall, feet at y = 0)
    or the garment's bounding box centre with its farthest vertex."""
    if framing == "body":
        return np.array([0.0, 0.5 * height, 0.0]), 0.52 * height
    if framing == "garment":
        v = np.asarray(garment_vertices, np.float64)
        center = 0.5 * (v.min(axis=0) + v.max(axis=0))
        return center, GARMENT_FRAME_MARGIN * float(np.linalg.norm(v - center, axis=1).max())
    raise PGCDataError(f"synth preset: unknown framing '{framing}'; use 'body' or 'garment'")


def garment_gap(body: Mesh, garment: Mesh) -> dict[str, float]:
    """Clearance of the garment's vertices from the body surface, metres: min, 10th percentile, median,
    90th percentile, and the median over the top 15 % of the garment (shoulders, where it hangs)."""
    from pgc.sim.collision import signed_distance

    d = signed_distance(garment.vertices, body.vertices, body.faces)
    y = garment.vertices[:, 1]
    top = y >= np.quantile(y, 0.85)
    q10, q50, q90 = np.quantile(d, [0.1, 0.5, 0.9])
    return {"min": float(d.min()), "p10": float(q10), "median": float(q50), "p90": float(q90),
            "shoulders_median": float(np.median(d[top]))}


@dataclass
class SynthScene:
    """A synthetic scene before it is rendered: the resolved preset, the body, the ground truth, the dome cameras
    and the garment's clearance from the body (:func:`garment_gap`)."""

    preset: SynthPreset
    body: SynthBody
    ground_truth: GroundTruth
    cameras: list[Camera]
    gap: dict[str, float]


def resolve_preset(preset: str | SynthPreset, garment: str | None = None, fabric: str | None = None,
                   looseness: float | None = None, detail: str | None = None, fit: str | None = None,
                   capture_light: str | None = None) -> SynthPreset:
    """The preset (a name of :data:`PRESETS` or a SynthPreset) with the given overrides, its spp rounded up to
    what its sampler takes."""
    p = get_preset(preset) if isinstance(preset, str) else preset
    if p.sampler == "ldsampler":  # it takes powers of 4 only: round up rather than let Mitsuba warn
        p = replace(p, spp=int(4 ** np.ceil(np.log(max(p.spp, 1)) / np.log(4) - 1e-9)))
    return replace(p, garment=garment or p.garment, fabric=fabric or p.fabric, detail=detail or p.detail,
                   fit=fit or p.fit, looseness=p.looseness if looseness is None else float(looseness),
                   capture_light=capture_light or p.capture_light)


def build_scene(p: SynthPreset, seed: int, body_model: BodyModel, reporter: Reporter | None = None) -> SynthScene:
    """The scene of the resolved preset ``p`` and ``seed``: body, garment, fabric (textures, fibres, detail),
    capture light and dome cameras (stages 'synth_geometry' and 'synth_fabric')."""
    from pgc.synth import fabrics, garments, rig
    from pgc.synth.body import draw_phenotype, make_body
    from pgc.synth.detail import get_detail, make_detail, root_offsets
    from pgc.synth.ground_truth import GroundTruth

    reporter = reporter or Reporter.silent()
    fab = fabrics.get_fabric(p.fabric)
    light = rig.capture_light(p.capture_light)
    detail_spec = get_detail(p.detail)
    with reporter.stage("synth_geometry") as st:
        body = make_body(body_model, draw_phenotype(body_model, seed))
        cloth = garments.make_garment(body, p.garment, looseness=p.looseness, resolution=p.garment_edge, fit=p.fit)
        gap = garment_gap(body.mesh(), cloth)
        st.record(body_vertices=len(body.vertices), body_height_m=round(body.height, 3),
                  garment_vertices=len(cloth.vertices),
                  gap_median_mm=round(1000 * gap["median"], 1))
    with reporter.stage("synth_fabric") as st:
        material, normal_map = fabrics.make_material(fab, cloth, p.texture, seed)
        fibres = fabrics.make_fibres(fab, cloth, material, seed, p.fibre_scale)
        surface = None
        if detail_spec is not None:
            surface, height = make_detail(cloth, detail_spec, seed)
            if fibres is not None:
                fibres.offset = root_offsets(height, cloth, fibres.face, fibres.bary)
        st.record(fibres=0 if fibres is None else len(fibres.face),
                  detail_vertices=0 if surface is None else len(surface.offset))
    center, radius = framing_sphere(p.framing, body.height, cloth.vertices)
    cameras = rig.dome_cameras(p.views, p.resolution, p.resolution, center=center,
                               distance=1.55 * body.height, subject_radius=radius, seed=seed)
    gt = GroundTruth(body.mesh(), cloth, material, light, normal_map, fibres, detail=surface)
    return SynthScene(p, body, gt, cameras, gap)


def generate(out: str | os.PathLike, preset: str | SynthPreset = "default", garment: str | None = None,
             fabric: str | None = None, seed: int = 0, looseness: float | None = None,
             reporter: Reporter | None = None, detail: str | None = None, fit: str | None = None,
             capture_light: str | None = None, *, renderer: SceneRenderer, body_model: BodyModel) -> Capture:
    """Generate a synthetic capture into ``out``, rendered by ``renderer`` (the configuration's, see
    :func:`pgc.synth.render.scene_renderer`), of a body of ``body_model`` (the configuration's ``[body_model]``)
    with the phenotype :func:`pgc.synth.body.draw_phenotype` draws for ``seed``, and return it (as written).

    The same arguments give byte-identical files. ``preset``: a name of :data:`PRESETS` or a SynthPreset;
    ``garment``, ``fabric``, ``looseness``, ``detail``, ``fit`` and ``capture_light`` override the preset's.
    """
    from pgc.io.capture import write_capture
    from pgc.synth import rig
    from pgc.synth.contact_sheet import write_contact_sheet
    from pgc.synth.ground_truth import body_record, write_ground_truth
    from pgc.synth.motions import MOTIONS, motion_rotations

    p = resolve_preset(preset, garment, fabric, looseness, detail, fit, capture_light)
    reporter = reporter or Reporter.silent()
    out = Path(out)
    synth = build_scene(p, seed, body_model, reporter)
    body, gt, cameras, gap = synth.body, synth.ground_truth, synth.cameras, synth.gap
    cloth, fibres, surface, light = gt.garment, gt.fibres, gt.detail, gt.light
    geometry = gt.geometry()
    scene, labels = renderer.build_scene(geometry, light)
    empty, _ = renderer.build_scene(None, light)

    views = []
    with reporter.stage("synth_render", total=len(cameras), spp=p.spp) as st:
        for i, cam in enumerate(cameras):
            color, _ = renderer.render_color(scene, cam, p.spp, seed * 100003 + i, p.sampler)
            background, _ = renderer.render_color(empty, cam, min(p.spp, 16), seed * 100003 + i, p.sampler)
            layers = renderer.ground_truth_layers(scene, labels, geometry, cam, p.gt_samples)
            views.append(View(cam, color, layers["mask"], layers["segmentation"], background,
                              {"linear": color, "albedo": layers["albedo"], "depth": layers["depth"]}))
            st.progress(i + 1)

    metadata = {"generator": "pgc synth", "preset": asdict(p), "garment": p.garment, "fabric": p.fabric, "seed": seed,
                "looseness": p.looseness, "capture_light": p.capture_light, "ground_truth": "ground_truth/scene.json",
                "body": body_record(body)}
    capture = Capture(views, light=light, metadata=metadata)
    with reporter.stage("synth_write"):
        write_capture(out, capture)
        envmaps = {k: rig.relight_envmap(p.envmap_height, k, seed) for k in ("sky", "studio")}
        motions = {name: motion_rotations(name, body).astype(np.float32) for name in MOTIONS}
        manifest = dict(metadata, light_radiance=light.radiance.tolist(), skin_albedo=list(gt.skin_albedo),
                        integrator={"type": "path", "max_depth": 8, "rfilter": "box", "sampler": p.sampler,
                                    "background_spp": min(p.spp, 16)},
                        counts={"views": len(views), "body_vertices": len(body.vertices),
                                "garment_vertices": len(cloth.vertices),
                                "fibres": 0 if fibres is None else len(fibres.face),
                                "detail_vertices": 0 if surface is None else len(surface.offset),
                                "detail_level": 0 if surface is None else surface.level},
                        garment_gap_m=gap)
        write_ground_truth(out, gt, body, motions, envmaps, manifest)
        write_contact_sheet(out / "contact_sheet.png", views)
    capture.root = str(out)
    return capture
