"""Training data of the shipped albedo network (:class:`pgc.albedo.dataset.AlbedoData`): synthetic renders with
ground-truth albedo.

Each scene draws a garment (looseness, sleeve and hem length), a fabric preset (BRDF, weave, fibres) with
a random pattern and colour palette, and a light (the capture dome's, a random-tint constant one, or a
relighting environment map), and renders a few dome views with the path tracer of :mod:`pgc.synth` at the
``default`` capture preset's texture and mesh resolution; the ground-truth albedo, mask and garment coverage
come from the generator's exact ray-cast layers. Train and validation use different garment kinds
(``tshirt`` vs ``dress`` by default), so validation measures generalisation to garments never seen.
"""

from __future__ import annotations

import colorsys
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pgc.albedo.dataset import AlbedoData
from pgc.events import Reporter

if TYPE_CHECKING:
    from pgc.roles.body_model import BodyModel
    from pgc.roles.scene_renderer import SceneRenderer


def random_palette(rng: np.random.Generator, count: int) -> tuple[tuple[float, float, float], ...]:
    """``count`` linear-RGB colours with random hue, saturation and value (sRGB-uniform value)."""
    out = []
    for _ in range(count):
        r, g, b = colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0.0, 0.9), rng.uniform(0.15, 0.95))
        out.append(tuple(float(c) ** 2.2 for c in (r, g, b)))
    return tuple(out)


PATTERNS = ("stripes", "checks", "knit", "heather", "solid")
"""Base-colour patterns drawn for the training scenes (any fabric BRDF with any pattern)."""


def random_fabric(rng: np.random.Generator):
    """An in-family fabric preset (its BRDF, weave and sparse fibres; no fibre truth: their curves cost 3-5x the
    render time) with a random pattern (``+logo`` for 30 %) and palette."""
    from pgc.synth import fabrics

    names = sorted(name for name, fabric in fabrics.FABRICS.items() if fabric.hair is None)
    base = fabrics.get_fabric(names[int(rng.integers(len(names)))])
    pattern = PATTERNS[int(rng.integers(len(PATTERNS)))] + ("+logo" if rng.uniform() < 0.3 else "")
    return replace(base, pattern=pattern, colors=random_palette(rng, 3))


def random_light(rng: np.random.Generator):
    """A third each: the capture dome's constant light at a random intensity; a random-tint constant
    light; a relighting environment map (sky or studio, random rotation and tint)."""
    from pgc.synth import rig
    from pgc.types import Light

    kind = int(rng.integers(3))
    if kind == 0:
        return rig.capture_light(tuple(np.asarray(rig.DEFAULT_RADIANCE) * rng.uniform(0.6, 1.4)))
    tint = rng.uniform(0.7, 1.3, 3)
    if kind == 1:
        return Light(radiance=tint * rng.uniform(0.6, 1.4))
    env = rig.relight_envmap(32, ("sky", "studio")[int(rng.integers(2))], int(rng.integers(1 << 30)))
    return Light(radiance=tint, envmap=env, rotation_deg=float(rng.uniform(0, 360)))


def make_albedo_data(garment_kind: str, scenes: int, views: int, resolution: int, seed: int,
                     spp: int = 16, texture: int = 1024, sampler: str = "ldsampler", garment_edge: float = 0.02,
                     reporter: Reporter | None = None, *, renderer: SceneRenderer, body_model: BodyModel
                     ) -> AlbedoData:
    """Render ``scenes`` x ``views`` training images of ``garment_kind`` with ``renderer`` (the configuration's,
    see :func:`pgc.synth.render.scene_renderer`; deterministic in ``seed``).

    Defaults follow the ``default`` capture preset (texture, mesh resolution, low-discrepancy sampler);
    ``spp`` 16 of that sampler is about the noise of the capture (64 spp) doubled. Per scene: garment
    body (a phenotype of ``body_model``, :func:`pgc.synth.body.draw_phenotype`), garment looseness, sleeve and
    hem length, fabric (:func:`random_fabric`), light (:func:`random_light`) and the dome of cameras are random.
    """
    from pgc.synth import fabrics, garments, rig
    from pgc.synth.body import draw_phenotype, make_body
    from pgc.synth.ground_truth import GroundTruth
    reporter = reporter or Reporter.silent()
    out: dict[str, list[np.ndarray]] = {"images": [], "albedo": [], "mask": [], "garment": []}
    with reporter.stage(f"albedo_data_{garment_kind}", total=scenes * views) as st:
        for s in range(scenes):
            rng = np.random.default_rng([seed, s])
            body = make_body(body_model, draw_phenotype(body_model, int(rng.integers(1 << 30))))
            height = body.height
            fab = random_fabric(rng)
            cloth = garments.make_garment(body, garment_kind, looseness=float(rng.uniform(0.02, 0.05)),
                                          resolution=garment_edge, sleeve_length=float(rng.uniform(0.2, 0.9)),
                                          length=float(rng.uniform(0.8, 1.15)))
            material, normal_map = fabrics.make_material(fab, cloth, texture, int(rng.integers(1 << 30)))
            fibres = fabrics.make_fibres(fab, cloth, material, int(rng.integers(1 << 30)))
            light = random_light(rng)
            geometry = GroundTruth(body.mesh(), cloth, material, light, normal_map, fibres).geometry()
            scene, labels = renderer.build_scene(geometry, light)
            cams = rig.dome_cameras(views, resolution, resolution, center=(0.0, 0.5 * height, 0.0),
                                    distance=1.55 * height, subject_radius=0.52 * height,
                                    seed=int(rng.integers(1 << 30)))
            for c, cam in enumerate(cams):
                color, _ = renderer.render_color(scene, cam, spp, int(rng.integers(1 << 30)), sampler)
                layers = renderer.ground_truth_layers(scene, labels, geometry, cam, 2)
                out["images"].append(color)
                out["albedo"].append(layers["albedo"])
                out["mask"].append(layers["mask"])
                out["garment"].append(layers["garment_coverage"])
                st.progress(s * views + c + 1)
    return AlbedoData(*(np.stack(out[k]).astype(np.float32) for k in ("images", "albedo", "mask", "garment")))
