"""BRDF maths and the ``brdf`` role: LTC fits, energy (white furnace), reciprocity, backend agreement,
gradients and hard cases. Mitsuba's BSDFs are tested in test_brdf_mitsuba.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pgc.arrays import array_ops
from pgc.brdfs.maths import (EVALUATORS, ltc_coefficients, ltc_density, pgc_sheen_terms, sheen_albedo,
                             sheen_frame)
from pgc.brdfs.parameters import PARAMETERS
from pgc.brdfs.quadrature import directional_albedo
from pgc.errors import PGCConfigError, PGCDataError
from pgc.registry import default_registry

NP = array_ops("numpy")
WHITE = np.ones(3)
MODELS = ("lambertian", "disney", "pgc-sheen")
RANDOM_PARAMS = {
    "lambertian": lambda r: {},
    "disney": lambda r: {"roughness": r.random(), "sheen": 5 * r.random(), "sheen_tint": r.random()},
    "pgc-sheen": lambda r: {"roughness": r.random(), "sheen_color": r.random(3).tolist(),
                            "sheen_roughness": 0.01 + 0.99 * r.random()},
}


def _view(cos_theta: float) -> np.ndarray:
    return np.array([math.sqrt(max(1.0 - cos_theta ** 2, 0.0)), 0.0, cos_theta])


def _hemisphere(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v


# -- the published LTC fits, written out independently from the issue text (scalar Python) ---------------
def _fit_reference(x: float, y: float) -> tuple[float, float, float]:
    a = (2.58126 * x + 0.813703 * y) * y / (1 + 0.310327 * x ** 2 + 2.60994 * x * y)
    b = math.sqrt(1 - x) * (y - 1) * y ** 3 / (0.0000254053 + 1.71228 * x - 1.71506 * x * y + 1.34174 * y ** 2)
    s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y))
    m = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y ** 2))) / (0.046391 + y)
    o = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y))
    r = min(max(math.exp(-0.5 * ((x - m) / s) ** 2) / (s * math.sqrt(2 * math.pi)) + o, 0.0), 1.0)
    return a, b, r


def test_ltc_fits_reproduce_the_published_formulas() -> None:
    xs, ys = np.meshgrid(np.linspace(0, 1, 21), np.linspace(0.01, 1, 23), indexing="ij")
    a, b = ltc_coefficients(NP, xs, ys)
    r = sheen_albedo(NP, xs, ys)
    ref = np.array([[_fit_reference(x, y) for x, y in zip(rx, ry)] for rx, ry in zip(xs, ys)])
    np.testing.assert_allclose(a, ref[..., 0], rtol=1e-12)
    np.testing.assert_allclose(b, ref[..., 1], rtol=1e-5, atol=2e-6)  # sqrt(1 - x) floored at 1e-6 at x = 1
    np.testing.assert_allclose(r, ref[..., 2], rtol=1e-12, atol=1e-15)
    assert np.all(a > 0) and np.all(b <= 0) and np.all((r >= 0) & (r <= 1))
    # inputs outside the fitted range are clamped, not extrapolated
    np.testing.assert_allclose(sheen_albedo(NP, np.array(0.5), np.array(0.0)), sheen_albedo(NP, 0.5, 0.01))


@pytest.mark.parametrize("y", [0.01, 0.05, 0.3, 0.7, 1.0])
@pytest.mark.parametrize("x", [1.0, 0.5, 0.05, 1e-4])
def test_ltc_lobe_is_a_normalised_pdf(x: float, y: float) -> None:
    """D integrates to one over the hemisphere (also where it concentrates at the horizon)."""
    a, b = ltc_coefficients(NP, x, y)

    def lobe(L: np.ndarray, V: np.ndarray) -> np.ndarray:
        ax, ay = sheen_frame(NP, V[..., 0], V[..., 1])
        wx, wy = L[..., 0] * ax + L[..., 1] * ay, L[..., 1] * ax - L[..., 0] * ay
        return ltc_density(NP, a, b, wx, wy, L[..., 2])[..., None]

    assert directional_albedo(lobe, _view(x), n_cos=1024, n_phi=256)[0] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("cos_v", [1.0, 0.6, 0.2, 0.02])
def test_white_furnace(cos_v: float) -> None:
    """Hemispherical albedo with white colours: Lambertian exactly 1; the sheen layer reflects sigma_s R;
    the layered PGC model equals R + (1 - R) a_d (the H_s scaling removes what the sheen took); nothing
    exceeds 1 while the Disney diffuse itself does not (roughness <= 0.4)."""
    V = _view(cos_v)
    alb = lambda model, params, base=WHITE: directional_albedo(  # noqa: E731
        lambda L, V_: EVALUATORS[model](NP, L, V_, base, params), V, n_cos=512, n_phi=128)
    assert alb("lambertian", {}) == pytest.approx(np.ones(3), abs=1e-3)
    for y in (0.05, 0.5, 1.0):
        r = float(sheen_albedo(NP, cos_v, y))
        sheen_only = alb("pgc-sheen", {"roughness": 0.5, "sheen_color": [1, 1, 1], "sheen_roughness": y}, 0 * WHITE)
        assert sheen_only == pytest.approx(np.full(3, r), abs=1e-3)
        for rough in (0.0, 0.4, 1.0):
            a_d = alb("disney", {"roughness": rough, "sheen": 0.0, "sheen_tint": 0.0})[0]
            total = alb("pgc-sheen", {"roughness": rough, "sheen_color": [1, 1, 1], "sheen_roughness": y})
            assert total == pytest.approx(np.full(3, r + (1 - r) * a_d), abs=1e-3)
            assert np.all(total <= max(1.0, a_d) + 1e-3)
            if rough <= 0.4:
                assert a_d <= 1.0 + 1e-3 and np.all(total <= 1.0 + 1e-3)
    # Disney's sheen is added on top of its diffuse (not energy conserving): one unit adds at most 0.09
    # (the bound the Mitsuba sampler uses as this lobe's selection weight).
    added = alb("disney", {"roughness": 0.4, "sheen": 1.0, "sheen_tint": 0.0}) - alb(
        "disney", {"roughness": 0.4, "sheen": 0.0, "sheen_tint": 0.0})
    assert np.all(added >= 0) and np.all(added <= 0.09)


def test_disney_diffuse_gain_is_the_known_retroreflection() -> None:
    """Burley's diffuse is not energy conserving at high roughness: at roughness 1 and grazing view it
    reflects ~1.5x what it receives (documented in docs/pbr.md; the models inherit it)."""
    a = directional_albedo(lambda L, V: EVALUATORS["disney"](NP, L, V, WHITE, {"roughness": 1.0, "sheen": 0.0,
                                                                              "sheen_tint": 0.0}),
                           _view(0.01), n_cos=512, n_phi=128)[0]
    assert 1.45 < a < 1.6


@pytest.mark.parametrize("model", ["lambertian", "disney"])
def test_reciprocity(model: str) -> None:
    """Lambertian and Disney (diffuse and sheen depend on L, V symmetrically) satisfy f(L, V) = f(V, L);
    the PGC model's diffuse lobe too (its sheen lobe and H_s(o) are view-dependent by design)."""
    rng = np.random.default_rng(0)
    L, V = _hemisphere(rng, 1000), _hemisphere(rng, 1000)
    base = rng.random((1000, 3))
    params = RANDOM_PARAMS[model](rng)
    f_lv = EVALUATORS[model](NP, L, V, base, params) / L[:, 2:]
    f_vl = EVALUATORS[model](NP, V, L, base, params) / V[:, 2:]
    np.testing.assert_allclose(f_lv, f_vl, rtol=1e-12)
    _, d_lv, _, _ = pgc_sheen_terms(NP, L, V, 0.7, 0.4)
    _, d_vl, _, _ = pgc_sheen_terms(NP, V, L, 0.7, 0.4)
    np.testing.assert_allclose(d_lv / L[:, 2], d_vl / V[:, 2], rtol=1e-12)


@pytest.mark.agreement
@pytest.mark.parametrize("model", MODELS)
def test_numpy_torch_jax_agree(model: str) -> None:
    torch = pytest.importorskip("torch")
    jnp = pytest.importorskip("jax.numpy")
    rng = np.random.default_rng(1)
    for _ in range(3):
        L, V = _hemisphere(rng, 500), _hemisphere(rng, 500)
        base = rng.random((500, 3))
        params = RANDOM_PARAMS[model](rng)
        ref = EVALUATORS[model](NP, L, V, base, params)
        t = EVALUATORS[model](array_ops("torch"), torch.tensor(L), torch.tensor(V), torch.tensor(base), params)
        j = EVALUATORS[model](array_ops("jax"), jnp.asarray(L, jnp.float32), jnp.asarray(V, jnp.float32),
                              jnp.asarray(base, jnp.float32), params)
        np.testing.assert_allclose(t.numpy(), ref, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(np.asarray(j), ref, rtol=1e-5, atol=1e-5)


def test_torch_gradients_match_finite_differences() -> None:
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(2)
    L = torch.tensor(_hemisphere(rng, 8))
    V = torch.tensor(_hemisphere(rng, 8))
    base = torch.tensor(rng.random((8, 3)))
    ops = array_ops("torch")

    def f(rough, color, sr, b):
        return EVALUATORS["pgc-sheen"](ops, L, V, b, {"roughness": rough, "sheen_color": color, "sheen_roughness": sr})

    args = (torch.tensor(0.6, dtype=torch.float64, requires_grad=True),
            torch.tensor([0.7, 0.5, 0.3], dtype=torch.float64, requires_grad=True),
            torch.tensor(0.4, dtype=torch.float64, requires_grad=True), base.requires_grad_())
    assert torch.autograd.gradcheck(f, args, eps=1e-6, atol=1e-6, rtol=1e-4)
    def disney(r, t, s):
        return EVALUATORS["disney"](ops, L, V, base.detach(), {"roughness": r, "sheen": s, "sheen_tint": t})

    assert torch.autograd.gradcheck(disney, tuple(torch.tensor(v, dtype=torch.float64, requires_grad=True)
                                                  for v in (0.3, 0.5, 1.2)), eps=1e-6, atol=1e-6, rtol=1e-4)


HARD_L = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.0, -0.8], [1.0, 0.0, 1e-7], [0.0, 1.0, 1e-12],
                   [-1.0, 0.0, 1e-7], [0.0, 0.0, 1.0]])
HARD_V = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 1e-7], [1.0, 0.0, 1e-7],
                   [1.0, 0.0, 1e-7], [0.6, 0.0, -0.8]])


@pytest.mark.parametrize("model", MODELS)
def test_hard_cases_are_finite(model: str) -> None:
    """Grazing directions, light or view below the horizon, N parallel to V, parameters at (and beyond)
    their bounds: values and torch gradients are finite; below the horizon the result is exactly zero."""
    torch = pytest.importorskip("torch")
    corners = [{p.name: (v if p.size == 1 else [v] * 3) for p in PARAMETERS[model]}
               for v in (0.0, 1.0)]
    corners += [{p.name: (p.upper if p.size == 1 else [p.upper] * 3) for p in PARAMETERS[model]},
                {p.name: (p.lower if p.size == 1 else [p.lower] * 3) for p in PARAMETERS[model]}]
    for params in corners:
        for base in (WHITE, np.zeros(3)):
            out = EVALUATORS[model](NP, HARD_L, HARD_V, base, params)
            assert np.all(np.isfinite(out)) and np.all(out >= 0)
            assert np.all(out[[2, 6]] == 0)
            tp = {k: torch.tensor(v, dtype=torch.float64, requires_grad=True) for k, v in params.items()}
            L = torch.tensor(HARD_L, requires_grad=True)
            V = torch.tensor(HARD_V, requires_grad=True)
            b = torch.tensor(base, requires_grad=True)
            EVALUATORS[model](array_ops("torch"), L, V, b, tp).sum().backward()
            for g in [L.grad, V.grad, b.grad] + [t.grad for t in tp.values()]:
                assert g is None or torch.all(torch.isfinite(g))


def test_role_plugins_registered_with_the_papers_initial_values() -> None:
    reg = default_registry()
    inits = {}
    for name in MODELS:
        brdf = reg.create("brdf", name)
        inits[name] = brdf.initial_params()
        rng = np.random.default_rng(3)
        L, V = _hemisphere(rng, 10), _hemisphere(rng, 10)
        np.testing.assert_allclose(brdf.eval_cos(L, V, WHITE, {}),
                                   EVALUATORS[name](NP, L, V, WHITE, inits[name]))
    assert inits["lambertian"] == {}
    assert inits["disney"] == {"roughness": 0.8, "sheen": 1.4, "sheen_tint": 0.0}
    assert inits["pgc-sheen"] == {"roughness": 0.8, "sheen_color": [0.75, 0.73, 0.27], "sheen_roughness": 0.5}
    with pytest.raises(PGCDataError, match="unknown parameter"):
        reg.create("brdf", "pgc-sheen").eval_cos(L, V, WHITE, {"sheen": 1.0})
    with pytest.raises(PGCConfigError, match="unknown BRDF backend"):
        reg.create("brdf", "lambertian").eval_cos(L, V, WHITE, {}, backend="cupy")
