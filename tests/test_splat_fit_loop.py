"""The one splat-fit loop (pgc.splats.fit): torch and JAX run the same schedule and record the same figures;
the fit stops on held-out convergence, not on the clock, and the same inputs give the same fit."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.geometry.testscene import body_mesh, make_capture
from pgc.roles.splat_renderer import FitSplatsSettings
from pgc.splats.fit import adam_update, converged

FAST = {"gaussians_per_pixel": 0.5, "holdout_every": 4, "log_every": 10, "init_color": "views"}


@pytest.fixture(scope="module")
def scene():
    return make_capture(body_mesh(0.04), views=8, size=40)


def test_adam_update_matches_torch_adam():
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(0)
    p0 = rng.normal(size=(5, 3))
    grads = [rng.normal(size=(5, 3)) for _ in range(6)]
    p = torch.tensor(p0, requires_grad=True)
    optim = torch.optim.Adam([p], lr=0.01, eps=1e-15)
    mine, m, v = p0.copy(), np.zeros_like(p0), np.zeros_like(p0)
    for t, g in enumerate(grads, start=1):
        p.grad = torch.tensor(g)
        optim.step()
        mine, m, v = adam_update(mine, g, m, v, t, 0.01)
    np.testing.assert_allclose(mine, p.detach().numpy(), rtol=1e-12, atol=1e-14)


def test_convergence_rule():
    s = FitSplatsSettings(converge_db=0.1, converge_patience=2)
    assert not converged([20.0, 21.0], s)                     # not enough evaluations yet
    assert not converged([20.0, 21.0, 21.05, 21.2], s)        # the last two gained 0.2 dB over the best before
    assert converged([20.0, 21.0, 21.05, 20.9], s)            # the last two gained 0.05 dB < 0.1
    assert not converged([20.0, 21.0, 21.0, 21.0], s.model_copy(update={"converge_db": 0.0}))  # 0: never


@pytest.mark.slow
def test_torch_and_jax_follow_the_same_schedule_and_record_the_same_figures(scene):
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    from pgc_jax.splat.renderer import JaxSplatRenderer
    from pgc_torch.splat.renderer import TorchSplatRenderer

    capture, mesh = scene
    settings = dict(FAST, iterations=60, converge_every=20, converge_db=0.0)
    fits = {"torch": TorchSplatRenderer({"threads": 1}).fit(capture, mesh, settings),
            "jax": JaxSplatRenderer({"tile_size": 8, "chunk_size": 16}).fit(capture, mesh, settings)}
    t, j = fits["torch"], fits["jax"]
    assert set(t.figures) == set(j.figures)
    assert t.figures["iterations"] == j.figures["iterations"] == 60
    assert t.figures["stopped"] == j.figures["stopped"] == "iterations"
    assert t.figures["initial_gaussians"] == j.figures["initial_gaussians"]
    assert [p["iteration"] for p in t.figures["time_to_psnr"]] == [p["iteration"] for p in j.figures["time_to_psnr"]]
    assert t.heldout_views == j.heldout_views and t.heldout_views
    assert abs(t.figures["psnr_heldout"] - j.figures["psnr_heldout"]) < 0.5
    assert abs(t.figures["psnr_heldout_full"] - j.figures["psnr_heldout_full"]) < 0.5


@pytest.mark.slow
def test_the_fit_stops_on_heldout_convergence_and_repeats_bit_for_bit(scene):
    pytest.importorskip("torch")
    from pgc_torch.splat.renderer import TorchSplatRenderer

    capture, mesh = scene
    settings = dict(FAST, iterations=2000, converge_every=10, converge_patience=2, converge_db=0.5,
                    converge_after=0.0, select_count=False, select_sh=False)
    renderer = TorchSplatRenderer({"threads": 2})
    first, second = renderer.fit(capture, mesh, settings), renderer.fit(capture, mesh, settings)
    f = first.figures
    assert f["stopped"] == "converged" and f["iterations"] < 2000 and f["iterations"] % 10 == 0
    psnrs = [p["psnr_heldout"] for p in f["time_to_psnr"]]
    assert len(psnrs) == f["iterations"] // 10 and converged(psnrs, FitSplatsSettings(**settings))
    assert not converged(psnrs[:-1], FitSplatsSettings(**settings))  # it stopped at the first converged check
    assert second.figures["iterations"] == f["iterations"]
    for name in ("parent", "means", "quats", "log_scales", "opacity_logits", "sh"):
        assert getattr(first.gaussians, name).tobytes() == getattr(second.gaussians, name).tobytes(), name
