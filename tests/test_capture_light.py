"""The synthetic capture's light (pgc.synth.rig.capture_light), its round trip through the capture files, and the
material fit under the capture's known light: which light it takes, its refusals, the radiance gradient, and
recovery under the sky-sun environment (float64 study maths)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pgc.brdfs.fitdata import fit_light
from pgc.errors import PGCDataError, PGCPluginError
from pgc.io.capture import read_capture, write_capture
from pgc.roles.pbr_renderer import MaterialFitSettings
from pgc.sampling import envmap_directions
from pgc.synth import rig
from pgc.testing.pbr_scenes import checker_texture, folded_sheet, ring_cameras
from pgc.types import Capture, Light, Material, View


def _capture(light: Light | None, n_views: int = 2, size: int = 16) -> Capture:
    views = []
    for cam in ring_cameras(n_views, size=size):
        image = np.full((size, size, 3), 0.5, np.float32)
        inside = np.zeros((size, size), np.float32)
        inside[2:-2, 2:-2] = 1.0
        views.append(View(cam, image, mask=inside, segmentation=(2 * inside).astype(np.uint8)))
    return Capture(views, light=light)


def test_sky_sun_envmap_peak_irradiance_and_the_sun_share_of_upward_irradiance():
    env = rig.sky_sun_envmap(64).astype(np.float64)
    d, solid = envmap_directions(64, 128)
    radiance = env.reshape(-1, 3)
    # exposure: the brightest face gets the uniform unit light's irradiance pi (green), found near the sun
    e, a = math.radians(rig.SUN_ELEVATION_DEG), math.radians(rig.SUN_AZIMUTH_DEG)
    sun_dir = np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
    normals = np.concatenate([np.random.default_rng(0).normal(size=(2000, 3)), sun_dir[None]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    irradiance = np.clip(normals @ d.T, 0.0, None) @ (radiance[:, 1] * solid)
    assert irradiance.max() <= math.pi * (1 + 1e-3) and irradiance[-1] > 0.97 * math.pi
    up = np.clip(d[:, 1], 0.0, None)
    irradiance = (radiance[:, 1] * solid * up)
    sun = radiance[:, 1] > 10 * np.median(radiance[:, 1])
    assert 1 <= sun.sum() <= 12  # a disc of 3 degrees: a few pixels of a 64-row map
    # the disc's pixels also carry the sky behind the sun: 0.1 % of the upward irradiance
    np.testing.assert_allclose(irradiance[sun].sum() / irradiance.sum(), rig.SUN_FRACTION, rtol=3e-3)
    assert (d[sun] @ sun_dir).min() > math.cos(math.radians(4.0))


def test_capture_light_kinds_and_refusal():
    uniform = rig.capture_light("uniform")
    assert uniform.envmap is None
    np.testing.assert_allclose(uniform.radiance, rig.DEFAULT_RADIANCE)
    sky = rig.capture_light("sky-sun", envmap_height=16)
    assert sky.envmap.shape == (16, 32, 3) and sky.envmap.dtype == np.float32
    with pytest.raises(PGCDataError, match="unknown capture light 'studio'.*uniform, sky-sun"):
        rig.capture_light("studio")


def test_sky_sun_light_round_trips_through_the_capture_files(tmp_path):
    light = Light(np.array([1.0, 0.96, 0.9]), rig.sky_sun_envmap(16), rotation_deg=30.0)
    write_capture(tmp_path / "cap", _capture(light))
    back = read_capture(tmp_path / "cap").light
    np.testing.assert_array_equal(back.envmap, light.envmap)
    np.testing.assert_allclose(back.radiance, light.radiance)
    assert back.rotation_deg == 30.0


def test_fit_light_takes_the_capture_light_or_a_constant_and_refuses_a_missing_one():
    light = Light(np.array([1.2, 1.0, 0.8]), rig.sky_sun_envmap(16), rotation_deg=45.0)
    known = fit_light(_capture(light), "auto")
    assert known.source == "capture" and known.shape.envmap is light.envmap and known.shape.rotation_deg == 45.0
    np.testing.assert_array_equal(known.shape.radiance, np.ones(3))
    np.testing.assert_array_equal(known.radiance, light.radiance)
    fitted = known.light(np.array([0.5, 0.6, 0.7]))
    assert fitted.envmap is light.envmap and fitted.rotation_deg == 45.0
    assert known.record() == {"source": "capture", "kind": "envmap", "envmap_shape": [16, 32, 3],
                              "rotation_deg": 45.0}
    constant = fit_light(_capture(light), "constant")
    assert constant.source == "constant" and constant.shape.envmap is None
    np.testing.assert_array_equal(constant.radiance, np.ones(3))
    assert fit_light(_capture(None), "auto").source == "constant"
    with pytest.raises(PGCDataError, match="records no light.*stages.material.light = 'auto' or 'constant'"):
        fit_light(_capture(None), "capture")
    with pytest.raises(ValueError):
        MaterialFitSettings(light="sky")


def test_the_torch_pbr_renderer_refuses_to_fit():
    from pgc.registry import default_registry

    renderer = default_registry().create("pbr_renderer", "torch")
    with pytest.raises(PGCPluginError, match="cannot fit materials.*mitsuba"):
        renderer.fit(_capture(None), folded_sheet(n=4), Material("pgc-sheen", {}, checker_texture(8)))


@pytest.mark.slow
@pytest.mark.parametrize("envmap", [False, True], ids=["constant", "sky-sun"])
def test_fit_recovers_the_radiance_under_the_capture_light(envmap):
    """A Lambertian folded sheet (true texture: only the light's RGB radiance is fitted) rendered at 256 spp under
    a rotated sky-sun map or a constant: the 4-spp fit under the capture's light shape returns the radiance
    (a gradient taken from the noisy image itself instead of prb's decorrelated adjoint pass came out 30 % low)."""
    pytest.importorskip("mitsuba")
    from pgc.registry import default_registry

    radiance = np.array([1.3, 1.0, 0.8])
    light = Light(radiance, rig.sky_sun_envmap(16) if envmap else None, 60.0)
    texture = checker_texture(16)
    truth = Material("lambertian", {}, texture)
    mesh = folded_sheet(n=12)
    reference = default_registry().create("pbr_renderer", "mitsuba", {"spp": 256, "max_depth": 2})
    views = []
    for cam in ring_cameras(4, size=24, radius=1.9, arc_deg=150, elevation_deg=20):
        out = reference.render(mesh, truth, light, cam)
        views.append(View(cam, out.color, mask=out.alpha, segmentation=(out.alpha > 0.5).astype(np.uint8) * 2))
    capture = Capture(views, light=Light(np.ones(3), light.envmap, light.rotation_deg))
    settings = MaterialFitSettings(lr=0.04, patience=25, max_iterations=300, max_image_side=24, max_depth=2,
                                   shards=1)
    fit = reference.fit(capture, mesh, Material("lambertian", {}, texture), settings)
    assert fit.figures["light"]["source"] == "capture"
    assert (fit.light.envmap is None) == (not envmap) and fit.light.rotation_deg == 60.0
    np.testing.assert_allclose(fit.light.radiance, radiance, rtol=0.03)


@pytest.mark.slow
def test_recovery_under_the_sky_sun_capture_environment():
    """The study's fit (Levenberg-Marquardt, float64) on a cotton-coloured patch lit by the capture's own sky-sun
    map: every fitted parameter within 10 % of the truth from the paper's initial values."""
    pytest.importorskip("torch")
    from pgc.brdfs import identifiability as ident

    scene = ident.study_scene(((0.70, 0.69, 0.66), (0.03, 0.05, 0.16), (0.62, 0.05, 0.04)), n_points=40,
                              n_views=4)
    frames = [ident.envmap_frame(rig.sky_sun_envmap(8), rotation_deg=30.0, name="sky-sun")]
    truth = ident.parameter_vector([1, 1, 1], [1.0, 0.96, 0.9], 0.9, [0.3, 0.25, 0.2], 0.5)
    start = ident.parameter_vector([1, 1, 1], [1, 1, 1], 0.8, [0.75, 0.73, 0.27], 0.5)
    fitted = ident.recover(scene, frames, truth, start, noise=0.002, iterations=15)
    cols = [ident.PARAMETER_NAMES.index(n) for n in ident.FIT_PARAMETERS]
    error = np.abs(fitted[cols] - truth[cols]) / truth[cols]
    assert error.max() < 0.1, dict(zip(ident.FIT_PARAMETERS, error.round(3)))


def test_synth_refuses_an_unknown_capture_light_before_any_work(tmp_path):
    from pgc.synth.generate import generate

    with pytest.raises(PGCDataError, match="unknown capture light 'studio'"):
        generate(tmp_path / "cap", "tiny", capture_light="studio", renderer=None, body_model=None)
    assert not (tmp_path / "cap").exists()


@pytest.mark.slow
def test_synth_records_the_sky_sun_light_in_the_capture_and_the_ground_truth(tmp_path):
    """``pgc synth --capture-light sky-sun``: the light comes back from transforms.json and from ground_truth/
    (map, radiance, kind), and the capture's metadata names it."""
    pytest.importorskip("mitsuba")
    from pgc.cli import main
    from pgc.io.limits import read_json
    from pgc.synth.ground_truth import read_ground_truth

    out = tmp_path / "cap"
    assert main(["synth", str(out), "--preset", "tiny", "--views", "2", "--resolution", "32",
                 "--capture-light", "sky-sun"]) == 0
    expected = rig.capture_light("sky-sun")
    for light in (read_capture(out).light, read_ground_truth(out).light):
        np.testing.assert_array_equal(light.envmap, expected.envmap)
        np.testing.assert_allclose(light.radiance, expected.radiance)
        assert light.rotation_deg == 0.0
    assert read_capture(out).metadata["capture_light"] == "sky-sun"
    assert read_json(out / "ground_truth" / "light.json", "light.json")["kind"] == "sky-sun"


def _bench_capture_light():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_capture_light.py"
    spec = importlib.util.spec_from_file_location("bench_capture_light", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


@pytest.mark.slow
def test_the_oracle_capture_with_every_mismatch_removed_is_the_fits_forward_model(
        tmp_path, default_scene_renderer, default_body_model):
    """benchmarks/bench_capture_light.py's oracle: with nothing removed it renders the capture again to the bit;
    with every mismatch removed the truth's scene renders what the material fit's forward model (the PBR
    renderer with the grey occluder, at the fit's path length) renders, on the fit's pixels, to within the
    two renders' noise."""
    pytest.importorskip("mitsuba")
    from pgc.brdfs.fitdata import fit_light, prepare_views
    from pgc.config import load
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.ground_truth import read_ground_truth

    bench = _bench_capture_light()
    cfg = load(require_available=False)
    folder = tmp_path / "knit"
    capture = generate(folder, get_preset("tiny", views=2, resolution=32, spp=16, framing="garment"),
                       fabric="knit-sheen", seed=3,
                       capture_light="sky-sun", renderer=default_scene_renderer, body_model=default_body_model)
    gt = read_ground_truth(folder)
    assert gt.normal_map is not None and gt.fibres is not None  # a control with every mismatch present
    for view, again in zip(capture.views, bench.oracle_views(folder, (), cfg)):
        np.testing.assert_array_equal(again.extras["linear"], view.extras["linear"])

    spp, depth = 256, cfg.stage("material").max_depth
    renderer, scene, _, geometry, _ = bench.oracle_scene(folder, bench.MISMATCHES, cfg)
    assert geometry.normal_map is None and geometry.fibres is None and renderer.options.max_depth == depth
    pbr = cfg.create("pbr_renderer")
    assert geometry.skin_albedo == (pbr.options.occluder_albedo,) * 3
    light = fit_light(capture, "capture").light(gt.light.radiance)
    fit_renderers = [type(pbr)(pbr.options.model_copy(update={"seed": seed})) for seed in (1, 2)]
    for fit_view, view in zip(prepare_views(capture, 32), capture.views):
        inside = fit_view.weight > 0  # the fit's pixels: the eroded garment interior
        truth = np.stack([renderer.render_color(scene, view.camera, spp, seed, "independent")[0][inside]
                          for seed in (1, 2)])
        fit = np.stack([r.render(gt.garment, gt.material, light, view.camera, spp=spp, occluder=gt.body,
                                 max_depth=depth).color[inside] for r in fit_renderers])
        # the standard error of the difference of the two means, from each renderer's two seeds
        error = np.sqrt(sum(np.var(x[0] - x[1], axis=0) / 2 for x in (truth, fit)) / (2 * inside.sum()))
        assert inside.sum() > 100
        np.testing.assert_array_less(np.abs(fit.mean((0, 1)) - truth.mean((0, 1))), 4 * error)
