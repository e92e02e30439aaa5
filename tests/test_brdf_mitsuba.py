"""The Mitsuba Python BSDFs: agreement with the shared maths and with Mitsuba's ``principled``, sampling
(chi-square against the pdf), texture orientation, two-sidedness and gradients."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.arrays import array_ops
from pgc.brdfs.maths import EVALUATORS
from pgc.errors import PGCDataError
from pgc.types import Material

mi_runtime = pytest.importorskip("pgc_mitsuba.runtime")
mi = mi_runtime.mitsuba()
dr = pytest.importorskip("drjit")
from pgc_mitsuba.bsdfs import material_to_bsdf  # noqa: E402

CASES = [
    ("lambertian", {}),
    ("disney", {"roughness": 0.6, "sheen": 2.0, "sheen_tint": 0.4}),
    ("pgc-sheen", {"roughness": 0.3, "sheen_color": [0.6, 0.5, 0.2], "sheen_roughness": 0.35}),
    ("pgc-sheen", {"roughness": 1.0, "sheen_color": [1.0, 1.0, 1.0], "sheen_roughness": 0.01}),
]


def _hemisphere(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v


def _interaction(V: np.ndarray, uv: tuple[float, float] = (0.5, 0.5)):
    si = dr.zeros(mi.SurfaceInteraction3f, len(V))
    si.wi = mi.Vector3f(V.T.astype(np.float32))
    si.uv = mi.Point2f(*uv)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    return si


def _eval(bsdf, V: np.ndarray, L: np.ndarray) -> np.ndarray:
    return np.array(bsdf.eval(mi.BSDFContext(), _interaction(V), mi.Vector3f(L.T.astype(np.float32)))).T


@pytest.mark.parametrize("model,params", CASES)
def test_mitsuba_eval_matches_shared_maths(model: str, params: dict) -> None:
    rng = np.random.default_rng(0)
    L, V = _hemisphere(rng, 2000), _hemisphere(rng, 2000)
    base = [0.3, 0.5, 0.7]
    bsdf = mi.load_dict(material_to_bsdf(Material(model, dict(params, base_color=base))))
    ref = EVALUATORS[model](array_ops("numpy"), L, V, np.array(base), params)
    got = _eval(bsdf, V, L)
    np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("roughness,sheen,tint", [(0.0, 0.0, 0.0), (0.8, 1.4, 0.0), (0.3, 0.7, 1.0), (1.0, 1.0, 0.5)])
def test_disney_matches_mitsuba_principled(roughness: float, sheen: float, tint: float) -> None:
    """Independent oracle: Mitsuba's C++ principled BSDF with specular/metallic/clearcoat/transmission at 0."""
    rng = np.random.default_rng(1)
    L, V = _hemisphere(rng, 2000), _hemisphere(rng, 2000)
    base = [0.2, 0.5, 0.3]
    ours = mi.load_dict(material_to_bsdf(Material("disney", dict(roughness=roughness, sheen=sheen,
                                                                    sheen_tint=tint, base_color=base))))
    ref = mi.load_dict({"type": "principled", "base_color": {"type": "rgb", "value": base}, "roughness": roughness,
                        "sheen": sheen, "sheen_tint": tint, "specular": 0.0, "metallic": 0.0, "clearcoat": 0.0,
                        "spec_trans": 0.0})
    np.testing.assert_allclose(_eval(ours, V, L), _eval(ref, V, L), atol=1e-6)


def _chi2(bsdf_dict: dict, theta_deg: float) -> float:
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    t = np.radians(theta_deg)
    wi = mi.Vector3f(float(np.sin(t)), 0.0, float(np.cos(t)))
    sample, pdf = BSDFAdapter(bsdf_dict["type"], bsdf_dict, wi=wi)
    chi = ChiSquareTest(domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3,
                        sample_count=200_000, res=64)
    assert chi.run(), f"chi-square rejected the sampler (p = {chi.p_value})"
    # the tabulated pdf integrates to one (sampling covers every direction where the BRDF is nonzero)
    assert abs(float(np.sum(chi.pdf)) / 200_000 - 1.0) < 2e-2
    return chi.p_value


@pytest.mark.parametrize("theta", [0.0, 60.0, 85.0])
@pytest.mark.parametrize("model,params", CASES[:3])
def test_sampling_matches_pdf(model: str, params: dict, theta: float) -> None:
    _chi2(material_to_bsdf(Material(model, dict(params, base_color=[0.3, 0.5, 0.7]))), theta)


@pytest.mark.parametrize("theta", [0.0, 60.0, 89.0])
@pytest.mark.parametrize("sheen_roughness", [0.2, 0.5, 1.0])
def test_ltc_sheen_lobe_sampled_exactly(sheen_roughness: float, theta: float) -> None:
    """Black base colour: only the Zeltner lobe remains, sampled through the inverse LTC.

    Below sheen roughness ~0.2 the lobe concentrates at the horizon more sharply than the 64x128
    histogram resolves; there the pdf's normalisation is checked by quadrature in test_brdf.py instead.
    """
    _chi2(material_to_bsdf(Material("pgc-sheen", dict(sheen_roughness=sheen_roughness, sheen_color=[1, 1, 1],
                                                       base_color=[0, 0, 0]))), theta)


@pytest.mark.parametrize("model,params", CASES)
def test_sample_weight_is_eval_over_pdf(model: str, params: dict) -> None:
    rng = np.random.default_rng(2)
    n = 4000
    V = _hemisphere(rng, n)
    bsdf = mi.load_dict(material_to_bsdf(Material(model, dict(params, base_color=[0.3, 0.5, 0.7]))))
    si = _interaction(V)
    ctx = mi.BSDFContext()
    bs, weight = bsdf.sample(ctx, si, mi.Float(rng.random(n).astype(np.float32)),
                             mi.Point2f(rng.random((2, n)).astype(np.float32)))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    w, v, p, p_bs = np.array(weight).T, np.array(value).T, np.array(pdf), np.array(bs.pdf)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    ok = p_bs > 0
    assert ok.mean() > 0.99
    np.testing.assert_allclose(p[ok], p_bs[ok], rtol=1e-4)
    np.testing.assert_allclose(w[ok], v[ok] / p[ok, None], rtol=1e-4, atol=1e-6)


def test_two_sided_back_hit_mirrors_front() -> None:
    rng = np.random.default_rng(3)
    L, V = _hemisphere(rng, 500), _hemisphere(rng, 500)
    model, params = CASES[2]
    d = material_to_bsdf(Material(model, dict(params, base_color=[0.3, 0.5, 0.7])))
    bsdf = mi.load_dict(d)
    flip = np.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose(_eval(bsdf, V * flip, L * flip), _eval(bsdf, V, L), atol=1e-7)
    one_sided = mi.load_dict(dict(d, two_sided=False))
    assert np.all(_eval(one_sided, V * flip, L * flip) == 0)


def test_texture_is_v_up() -> None:
    """pgc UVs have v up: v = 0.9 reads the top rows of the texture array."""
    tex = np.zeros((8, 8, 3), np.float32)
    tex[:4] = [1.0, 0.0, 0.0]
    tex[4:] = [0.0, 1.0, 0.0]
    bsdf = mi.load_dict(material_to_bsdf(Material("lambertian", base_color=tex)))
    V = np.array([[0.0, 0.0, 1.0]])
    for v, expected in ((0.9, [1, 0, 0]), (0.1, [0, 1, 0])):
        si = _interaction(V, uv=(0.5, v))
        got = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(0, 0, 1))).T[0] * np.pi
        np.testing.assert_allclose(got, expected, atol=1e-6)


def test_gradient_matches_finite_difference() -> None:
    """d(eval)/d(sheen_roughness) through Dr.Jit AD equals a central difference of the evaluation."""
    rng = np.random.default_rng(4)
    L, V = _hemisphere(rng, 64), _hemisphere(rng, 64)
    mat = Material("pgc-sheen", dict(roughness=0.4, sheen_color=[0.8, 0.6, 0.3], sheen_roughness=0.45,
                                     base_color=[0.3, 0.5, 0.7]))
    bsdf = mi.load_dict(material_to_bsdf(mat))
    params = mi.traverse(bsdf)
    key = "sheen_roughness"
    dr.enable_grad(params[key])
    params.update()
    value = bsdf.eval(mi.BSDFContext(), _interaction(V), mi.Vector3f(L.T.astype(np.float32)))
    total = dr.sum(value[0] + value[1] + value[2])
    dr.backward(total)
    grad = float(dr.grad(params[key])[0])
    h = 1e-3
    sums = []
    for y in (0.45 + h, 0.45 - h):
        m = Material("pgc-sheen", dict(mat.params, sheen_roughness=y))
        sums.append(EVALUATORS["pgc-sheen"](array_ops("numpy"), L, V, np.array([0.3, 0.5, 0.7]), m.params).sum())
    fd = (sums[0] - sums[1]) / (2 * h)
    assert grad == pytest.approx(fd, rel=1e-3)


def test_bad_material_errors_name_the_field() -> None:
    with pytest.raises(PGCDataError, match="sheen_color"):
        material_to_bsdf(Material("pgc-sheen", {"sheen_color": [1, 2], "base_color": [0.5] * 3}))
    with pytest.raises(PGCDataError, match="base_color"):
        material_to_bsdf(Material("lambertian"))
    with pytest.raises(PGCDataError, match="no Mitsuba BSDF"):
        material_to_bsdf(Material("phong", {"base_color": [0.5] * 3}))
