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
            "jax": JaxSplatRenderer({"compositor": "xla", "tile_size": 8, "chunk_size": 16}).fit(capture, mesh, settings),
            "jax-fused": JaxSplatRenderer({"compositor": "fused", "threads": 1}).fit(capture, mesh, settings)}
    t, j = fits["torch"], fits["jax"]
    assert set(t.figures) == set(j.figures)
    assert t.figures["iterations"] == j.figures["iterations"] == 60
    assert t.figures["stopped"] == j.figures["stopped"] == "iterations"
    assert t.figures["initial_gaussians"] == j.figures["initial_gaussians"]
    assert [p["iteration"] for p in t.figures["time_to_psnr"]] == [p["iteration"] for p in j.figures["time_to_psnr"]]
    assert t.heldout_views == j.heldout_views and t.heldout_views
    assert abs(t.figures["psnr_heldout"] - j.figures["psnr_heldout"]) < 0.5
    assert abs(t.figures["psnr_heldout_full"] - j.figures["psnr_heldout_full"]) < 0.5
    # the JAX fit on the compiled kernel: the torch fit's kernel, JAX's binding, losses and Adam
    # (the same kernel: the held-out PSNR along the fit agrees to 0.1 dB; after pruning and selection, discrete
    # choices on this 40 px scene, to 0.5 dB as for the traced compositor)
    f = fits["jax-fused"]
    assert set(f.figures) == set(t.figures) and f.figures["iterations"] == 60
    for a, b in zip(t.figures["time_to_psnr"], f.figures["time_to_psnr"], strict=True):
        assert abs(a["psnr_heldout"] - b["psnr_heldout"]) < 0.1
    assert abs(t.figures["psnr_heldout"] - f.figures["psnr_heldout"]) < 0.5


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


def test_a_capture_with_no_heldout_view_stops_on_the_training_psnr_plateau(scene):
    """Too few views to hold one out: the convergence test runs on the training views' PSNR, so the fit still
    stops before its cap, and the curve names what it measured."""
    pytest.importorskip("torch")
    from pgc_torch.splat.renderer import TorchSplatRenderer

    capture, mesh = scene
    settings = dict(FAST, holdout_every=len(capture.views) + 1, iterations=2000, converge_every=10,
                    converge_patience=2, converge_db=0.5, converge_after=0.0, select_count=False, select_sh=False)
    fit = TorchSplatRenderer({"threads": 1}).fit(capture, mesh, settings)
    f = fit.figures
    assert f["views_heldout"] == 0 and not fit.heldout_views
    assert f["stopped"] == "converged" and f["iterations"] < 2000
    psnrs = [p["psnr_train"] for p in f["time_to_psnr"]]
    assert all("psnr_heldout" not in p for p in f["time_to_psnr"])
    assert len(psnrs) == f["iterations"] // 10 and converged(psnrs, FitSplatsSettings(**settings))
    assert not converged(psnrs[:-1], FitSplatsSettings(**settings))


def _state(opacity: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    n = len(opacity)
    logits = np.log(opacity) - np.log1p(-opacity)
    arrays = {"means": rng.normal(size=(n, 3)), "quats": rng.normal(size=(n, 4)),
              "log_scales": rng.normal(-2, 0.1, size=(n, 3)), "opacity_logits": logits, "sh": rng.normal(size=(n, 4, 3))}
    state = {"parent": np.arange(n) * 10}
    for name, a in arrays.items():
        state[f"p_{name}"] = a.astype(np.float32)
        state[f"m_{name}"] = np.ones_like(a, np.float32)
        state[f"v_{name}"] = np.ones_like(a, np.float32)
    return state


def test_relocation_moves_dead_gaussians_and_keeps_each_stack_s_opacity():
    from pgc.splats.fit import relocate

    rng = np.random.default_rng(0)
    opacity = np.array([0.9, 0.001, 0.5, 0.002, 0.0001, 0.3])
    state = _state(opacity, rng)
    before = {k: v.copy() for k, v in state.items()}
    moved = relocate(state, np.random.default_rng(1), 0.005)
    assert moved == 3 and all(v.shape == before[k].shape for k, v in state.items())
    dead, live = [1, 3, 4], [0, 2, 5]
    new_opacity = 1.0 / (1.0 + np.exp(-state["p_opacity_logits"].astype(np.float64)))
    for src in live:  # a source and its copies composite to the source's old opacity
        stack = [src] + [d for d in dead if state["parent"][d] == before["parent"][src]]
        assert np.allclose(new_opacity[stack], new_opacity[src])
        np.testing.assert_allclose(1 - np.prod(1 - new_opacity[stack]), opacity[src], rtol=1e-5)
        if len(stack) == 1:  # not drawn: untouched
            for k in state:
                np.testing.assert_array_equal(state[k][src], before[k][src])
    for d in dead:
        src = int(np.flatnonzero(before["parent"] == state["parent"][d])[0])
        assert src in live
        for name in ("quats", "log_scales", "sh"):
            np.testing.assert_array_equal(state[f"p_{name}"][d], before[f"p_{name}"][src])
        assert 0 < np.abs(state["p_means"][d] - before["p_means"][src]).max() < 0.2  # jittered by ~0.5 local scale
        assert all(np.all(state[f"{m}_{n}"][d] == 0) for m in "mv" for n in ("means", "sh"))
    again = _state(opacity, np.random.default_rng(0))
    relocate(again, np.random.default_rng(1), 0.005)
    assert all(np.array_equal(again[k], state[k]) for k in state)  # seeded: the same moves
    assert relocate(_state(np.full(4, 0.5), rng), rng, 0.005) == 0  # nothing dead: nothing moves


@pytest.mark.slow
def test_fit_with_relocation_moves_gaussians_and_stays_finite(scene):
    pytest.importorskip("torch")
    from pgc_torch.splat.renderer import TorchSplatRenderer

    capture, mesh = scene
    settings = dict(FAST, iterations=40, converge_db=0.0, relocate_every=10, relocate_opacity=0.09,
                    select_count=False, select_sh=False, keep="all", prune_weight=0.0)
    fit = TorchSplatRenderer({"threads": 1}).fit(capture, mesh, settings)
    g = fit.gaussians
    assert fit.figures["relocated"] > 0 and len(g) == fit.figures["initial_gaussians"]
    assert all(np.all(np.isfinite(getattr(g, n))) for n in ("means", "quats", "log_scales", "opacity_logits", "sh"))
    assert g.parent.min() >= 0 and g.parent.max() < len(mesh.faces)


@pytest.mark.slow
def test_surface_and_opacity_terms_act_in_both_backends(scene):
    """lambda_surface keeps Gaussians on their triangles; lambda_opacity fades the Gaussians out."""
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    from pgc_jax.splat.renderer import JaxSplatRenderer
    from pgc_torch.splat.renderer import TorchSplatRenderer

    capture, mesh = scene
    settings = dict(FAST, iterations=15, converge_db=0.0, select_count=False, select_sh=False, keep="all",
                    prune_weight=0.0, lr_position=2e-3, lr_position_final=2e-3)
    for renderer in (TorchSplatRenderer({"threads": 1}), JaxSplatRenderer({"compositor": "xla"}),
                     JaxSplatRenderer({"compositor": "fused"})):
        free = renderer.fit(capture, mesh, dict(settings, lambda_surface=0.0)).gaussians
        held = renderer.fit(capture, mesh, dict(settings, lambda_surface=100.0)).gaussians
        offset = {k: float(np.sqrt(np.mean(g.means[:, 1] ** 2))) for k, g in (("free", free), ("held", held))}
        assert offset["held"] < 0.5 * offset["free"], (type(renderer).__name__, offset)
        if getattr(renderer, "compositor", None) == "xla":
            continue  # the opacity term is the same traced code on both JAX compositors; one of them suffices
        faded = renderer.fit(capture, mesh, dict(settings, lambda_opacity=10.0)).gaussians
        opacity = {k: float(np.mean(1 / (1 + np.exp(-g.opacity_logits)))) for k, g in (("free", free),
                                                                                        ("faded", faded))}
        assert opacity["faded"] < 0.8 * opacity["free"], (type(renderer).__name__, opacity)


def test_torch_in_place_adam_gives_the_same_bits_as_the_shared_update():
    torch = pytest.importorskip("torch")
    from pgc_torch.splat.fit import adam_update_in_place

    rng = np.random.default_rng(1)
    p0 = torch.tensor(rng.normal(size=(7, 4, 3)), dtype=torch.float32)
    lr = torch.tensor(np.array([[0.01], [0.0005], [0.0005], [0.0005]]), dtype=torch.float32)  # per SH band
    p, m, v = p0.clone(), torch.zeros_like(p0), torch.zeros_like(p0)
    ref, rm, rv = p0.clone(), torch.zeros_like(p0), torch.zeros_like(p0)
    for t in range(1, 9):
        g = torch.tensor(rng.normal(size=p0.shape) * 10.0 ** rng.integers(-6, 3), dtype=torch.float32)
        ref, rm, rv = adam_update(ref, g, rm, rv, t, lr)
        adam_update_in_place(p, g.clone(), m, v, t, lr, torch.empty_like(p))
        assert torch.equal(p, ref) and torch.equal(m, rm) and torch.equal(v, rv)
