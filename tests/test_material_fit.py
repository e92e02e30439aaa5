"""Material fitting by differentiable path tracing, and model selection, on scenes rendered here with a
known material and light (a folded cloth sheet seen by a ring of cameras)."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.brdfs.fitdata import masked_mse, prepare_views
from pgc.brdfs.parameters import PARAMETERS
from pgc.testing.pbr_scenes import checker_texture, folded_sheet, ring_cameras
from pgc.brdfs.select import fit_and_select, holdout_split
from pgc.errors import PGCDataError
from pgc.roles.pbr_renderer import MaterialFitSettings
from pgc.registry import default_registry
from pgc.types import Capture, Light, Material, View

pytest.importorskip("mitsuba")
LIGHT = np.array([2.0, 1.6, 1.2])
FAST = MaterialFitSettings(lr=0.04, patience=25, max_iterations=200, max_image_side=24, holdout_every=3, eval_spp=32,
                           max_depth=2)
"""Test settings: a larger step than the paper's 0.01 so that tests converge in ~100 steps; direct light."""


def synthetic_capture(material: Material, n_views: int = 6, size: int = 32, spp: int = 128) -> Capture:
    """Ground-truth images of the folded sheet under a constant light of radiance LIGHT."""
    renderer = default_registry().create("pbr_renderer", "mitsuba", {"spp": spp, "max_depth": 2})
    mesh = folded_sheet(n=16)
    views = []
    for cam in ring_cameras(n_views, size=size, radius=1.9, arc_deg=150, elevation_deg=20):
        out = renderer.render(mesh, material, Light(LIGHT), cam)
        views.append(View(cam, out.color, mask=out.alpha, segmentation=(out.alpha > 0.5).astype(np.uint8) * 2))
    return Capture(views, light=Light(LIGHT))


@pytest.fixture(scope="module")
def renderer():
    return default_registry().create("pbr_renderer", "mitsuba", {"spp": 32, "max_depth": 2})


SHEEN_TRUTH = {"roughness": 0.5, "sheen_color": [0.5, 0.45, 0.3], "sheen_roughness": 0.35}


@pytest.fixture(scope="module")
def sheen_fit(renderer):
    """pgc-sheen fitted from its defaults on a 6-view 32 px scene of the sheen truth, Adam then the polish at
    16 spp (Adam's end point, figures["polish"]["adam"], is what Adam alone returns: the polish starts from it).
    Over fit seeds 0, 1 and 2 the 16-spp polish converged in 7, 4 and 3 of its 10 iterations (9 at the default
    64 spp, seed 0), the light within 1.5 %."""
    texture = checker_texture(32)
    capture = synthetic_capture(Material("pgc-sheen", SHEEN_TRUTH, texture), n_views=6, size=32)
    fit = renderer.fit(capture, folded_sheet(n=16), Material("pgc-sheen", {}, texture),
                       FAST.model_copy(update={"max_image_side": 32, "polish": True, "polish_spp": 16}))
    return fit, capture, texture


@pytest.mark.slow
def test_fit_recovers_sheen_parameters_and_light(sheen_fit) -> None:
    """Adam alone (the default): its end point in the polished fit."""
    truth = SHEEN_TRUTH
    fit, capture, texture = sheen_fit
    p, f = dict(fit.figures["polish"]["adam"]), fit.figures
    radiance = np.array(p.pop("radiance"))
    assert f["stopped"] == "plateau" and f["iterations"] < FAST.max_iterations
    np.testing.assert_allclose(radiance, LIGHT, rtol=0.04)
    # 0.06 before the radiance became the emitter's own value (an unbiased radiance gradient); 0.062 measured after
    assert abs(p["sheen_roughness"] - truth["sheen_roughness"]) < 0.075
    # The sheen colour and the diffuse roughness are weakly constrained: the loss is nearly flat along them
    # compared with the 4-spp gradient noise, and the fit stops with them between the initial value and the
    # truth (measured here: sheen colour up to 0.24 off per channel, green still near its start 0.73). It
    # must have moved toward the truth, and the fitted model must reproduce the images: its noise-free error
    # is close to that of the true parameters (whose error is the targets' own Monte Carlo noise).
    init_color = np.array(PARAMETERS["pgc-sheen"][1].init)
    truth_color = np.array(truth["sheen_color"])
    assert np.linalg.norm(np.array(p["sheen_color"]) - truth_color) < np.linalg.norm(init_color - truth_color)
    assert 0.0 <= p["roughness"] <= 1.0
    reference = default_registry().create("pbr_renderer", "mitsuba", {"spp": 256, "max_depth": 2})
    errors = {}
    for name, (params, light) in {"truth": (truth, LIGHT), "fit": (p, radiance)}.items():
        errors[name] = np.mean([masked_mse(reference.render(folded_sheet(n=16), Material("pgc-sheen", params, texture),
                                                            Light(light), v.camera).color, v.target, v.weight)
                                for v in prepare_views(capture, 32)])
    assert errors["fit"] < 1.5 * errors["truth"], errors


@pytest.mark.slow
def test_polish_lowers_its_cost(sheen_fit) -> None:
    """The polish of the fit above lowers its cost from Adam's end point (so it found descent there: it did not
    stop as 'no_descent'), keeps the parameters in bounds and the light within 4 %. (The targets' 128-spp noise,
    about 0.03 per pixel, leaves the weakly determined roughness and sheen colour 10-40 % uncertain on this small
    scene, so the step at the initial damping stays above the tolerance and the polish ends on its iteration
    bound; tests/test_least_squares.py checks that the polish's estimator removes the render-noise bias.)"""
    fit = sheen_fit[0]
    polish, p = fit.figures["polish"], fit.material.params
    assert polish["stopped"] in ("converged", "iterations") and polish["loss_after"] < polish["loss_before"], polish
    assert 0.0 <= p["roughness"] <= 1.0 and 0.01 <= p["sheen_roughness"] <= 1.0
    assert all(0.0 <= c <= 1.0 for c in p["sheen_color"])
    np.testing.assert_allclose(fit.light.radiance, LIGHT, rtol=0.04)


def test_fitted_parameters_stay_in_bounds(renderer) -> None:
    """Large steps push the Disney parameters against their bounds; they are clamped, never beyond."""
    texture = checker_texture(32)
    capture = synthetic_capture(Material("lambertian", {}, texture), n_views=2, size=16, spp=16)
    fit = renderer.fit(capture, folded_sheet(n=8), Material("disney", {}, texture),
                       FAST.model_copy(update={"max_iterations": 8, "lr": 0.5}))
    p = fit.material.params
    assert 0.0 <= p["roughness"] <= 1.0 and 0.0 <= p["sheen"] <= 5.0 and 0.0 <= p["sheen_tint"] <= 1.0
    assert fit.figures["iterations"] == 8 and fit.figures["stopped"] == "max_iterations"
    assert np.all(np.isfinite(fit.light.radiance)) and np.all(fit.light.radiance > 0)


@pytest.mark.slow
def test_selection_picks_lambertian_on_the_lambertian_control(renderer) -> None:
    texture = checker_texture(32)
    capture = synthetic_capture(Material("lambertian", {}, texture), n_views=6, size=16, spp=64)
    sel = fit_and_select(renderer, capture, folded_sheet(n=16), Material("lambertian", {}, texture), FAST,
                         models=("lambertian", "pgc-sheen"))
    assert sel.fit.material.brdf == "lambertian", sel.reason
    assert set(sel.table) == {"lambertian", "pgc-sheen"}
    # the richer model cannot do much better on a Lambertian scene
    assert sel.table["pgc-sheen"]["psnr_holdout"] < sel.table["lambertian"]["psnr_holdout"] + FAST.margin_db
    assert sel.fit.figures["selection"]["chosen"] == "lambertian"
    np.testing.assert_allclose(sel.fit.light.radiance, LIGHT, rtol=0.04)  # the light alone is recovered


@pytest.mark.slow
def test_disney_reaches_its_lambertian_special_case(renderer) -> None:
    """Disney with sheen 0 and roughness ~0.3-0.5 is close to Lambert, so on a Lambertian scene its fit from the
    paper's start (sheen 1.4, roughness 0.8) must reach that special case: sheen near 0 and held-out PSNR within
    0.1 dB of the lambertian fit. Regression: with the parameters unscaled, sheen (range [0, 5]) travelled 5x
    slower than the roughness it trades off against; the loss stalled with the sheen still at 0.99 and the fit
    stopped 0.39 dB below lambertian here (on the synthetic knit: roughness 0.15, sheen 0.27, 0.35 dB below).
    At the test's lr 0.04 and 4 spp the gradient noise alone moves the end point over fit seeds (sheen 0.00 to
    0.52, up to 0.24 dB below); at 16 spp, over seeds 0, 300 and 123456: sheen 0.001 / 0.002 / 0.108 and
    0.00 / 0.00 / 0.07 dB below."""
    texture = checker_texture(32)
    capture = synthetic_capture(Material("lambertian", {}, texture), n_views=6, size=32, spp=64)
    sel = fit_and_select(renderer, capture, folded_sheet(n=16), Material("lambertian", {}, texture),
                         FAST.model_copy(update={"max_image_side": 32, "spp": 16}), models=("lambertian", "disney"))
    table = sel.table
    assert table["disney"]["psnr_holdout"] > table["lambertian"]["psnr_holdout"] - 0.1, table
    assert table["disney"]["params"]["sheen"] < 0.25, table["disney"]["params"]
    assert sel.fit.material.brdf == "lambertian", sel.reason


def test_holdout_split_and_bad_input() -> None:
    assert holdout_split(8, 4) == ([0, 1, 2, 4, 5, 6], [3, 7])
    with pytest.raises(PGCDataError, match="too few"):
        holdout_split(1, 2)
    capture = synthetic_capture(Material("lambertian", {"base_color": [0.5] * 3}), n_views=2, size=8, spp=4)
    for v in capture.views:
        v.segmentation[:] = 0
    renderer = default_registry().create("pbr_renderer", "mitsuba")
    with pytest.raises(PGCDataError, match="no view has garment pixels"):
        renderer.fit(capture, folded_sheet(n=4), Material("lambertian", {"base_color": [0.5] * 3}))
    with pytest.raises(PGCDataError, match="cannot be fitted"):
        renderer.fit(capture, folded_sheet(n=4), Material("phong", {"base_color": [0.5] * 3}))
