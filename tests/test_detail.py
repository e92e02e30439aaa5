"""The near field's detail in the hybrid (pgc.filtering.detail): additive h(G), multiplicative G / l(G), or h(G)
scaled by the far field's change from the capture light."""

import numpy as np
import pytest

from pgc import config as config_mod
from pgc.errors import PGCConfigError
from pgc.filtering.detail import DETAIL_MODES, GAIN_FLOOR, MAX_GAIN, detail_gain, hybrid_colour
from pgc.pipeline.compose import compose, unpremultiply
from pgc.pipeline.render import same_light
from pgc.registry import default_registry
from pgc.roles.splat_renderer import RenderOutput
from pgc.types import Light


def filters():
    reg = default_registry()
    return [reg.create("filter", name) for name in ("opencv", "torch", "jax")
            if ("filter", name) in reg.implementations and reg.get("filter", name).available]


def garment(rng, h=24, w=32, low=0.05):
    """A render with a covered garment (alpha 1 inside a rectangle, soft edge) of colours in [low, 1]."""
    alpha = np.zeros((h, w), np.float32)
    alpha[4:20, 5:27] = 1.0
    alpha[3, 5:27] = alpha[20, 5:27] = 0.5
    colour = rng.uniform(low, 1.0, (h, w, 3)).astype(np.float32)
    return RenderOutput(colour * alpha[..., None], alpha)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
@pytest.mark.parametrize("silhouette", ["near", "far"])
@pytest.mark.parametrize("detail", DETAIL_MODES)
def test_every_mode_reproduces_the_near_field_when_the_far_field_matches_it(filt, silhouette, detail):
    """At the capture pose under the capture light (S = G) the hybrid is G, whichever detail mode."""
    g = garment(np.random.default_rng(0))
    frame = compose(g, g, filt, 7, silhouette=silhouette, detail=detail, far_capture=g)
    # with the far silhouette the detail is weighted by the near alpha: G itself where the garment covers fully
    garment_px = g.alpha > 0.99 if silhouette == "far" else g.alpha >= 0
    np.testing.assert_allclose(frame.hybrid[garment_px], g.color[garment_px], atol=2e-5)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_multiplicative_detail_follows_a_scaled_light_and_additive_does_not(filt):
    """A far field c * G (a light c times the capture light, per channel): the multiplicative hybrid is c * G,
    the additive one G + (c - 1) l(G), clipped at 0 (a dimmer light leaves the capture-light detail negative)."""
    g = garment(np.random.default_rng(1))
    c = np.array([2.0, 0.5, 1.25], np.float32)
    s = RenderOutput(g.color * c, g.alpha)
    inside = g.alpha > 0.99
    mult = compose(g, s, filt, 9, detail="multiplicative")
    np.testing.assert_allclose(mult.hybrid[inside], (g.color * c)[inside], rtol=1e-4, atol=1e-5)
    add = compose(g, s, filt, 9, detail="additive")
    low_g = filt.lowpass(unpremultiply(g), g.alpha, 9)
    expected = np.maximum(g.color + (c - 1) * low_g, 0)
    np.testing.assert_allclose(add.hybrid[inside], expected[inside], rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_ratio_detail_scales_the_capture_light_hybrid_by_the_far_fields_change(filt):
    """Far field S_c under the capture light, c * S_c under a novel one: the ratio hybrid is c times the capture
    light's additive hybrid l(S_c) + h(G); without a capture-light far field it is the additive hybrid."""
    rng = np.random.default_rng(3)
    g = garment(rng)
    s_capture = garment(rng, low=0.1)
    s_capture = RenderOutput(s_capture.color, g.alpha)
    c = np.array([2.0, 0.5, 1.25], np.float32)
    relit = RenderOutput(s_capture.color * c, g.alpha)
    inside = g.alpha > 0.99
    capture_hybrid = compose(g, s_capture, filt, 9, detail="additive")
    ratio = compose(g, relit, filt, 9, detail="ratio", far_capture=s_capture)
    np.testing.assert_allclose(ratio.hybrid[inside], (c * capture_hybrid.hybrid)[inside], rtol=1e-4, atol=1e-5)
    same = compose(g, relit, filt, 9, detail="ratio")
    np.testing.assert_array_equal(same.hybrid, compose(g, relit, filt, 9, detail="additive").hybrid)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_residual_detail_keeps_the_relit_far_field_and_adds_the_near_fields_excess(filt):
    """Far field S_c = A under the capture light and S = A * L under a novel light whose shading L has its own
    fine detail (a bumpy surface lit from the side); near field G = S_c + D. The residual hybrid is S (its own
    high band included) plus l(S) (h(G) / l(G) - h(S_c) / l(S_c)); it is S itself when
    G = S_c, and the multiplicative hybrid under the capture light."""
    rng = np.random.default_rng(5)
    albedo = garment(rng, low=0.2)
    shading = rng.uniform(0.3, 1.5, albedo.color.shape).astype(np.float32)
    relit = RenderOutput(albedo.color * shading, albedo.alpha)
    near = RenderOutput(albedo.color + 0.05 * albedo.alpha[..., None] * rng.standard_normal(albedo.color.shape)
                        .astype(np.float32), albedo.alpha)
    inside = albedo.alpha > 0.99
    frame = compose(near, relit, filt, 9, detail="residual", far_capture=albedo)

    def split(render):
        colour = unpremultiply(render)
        low = filt.lowpass(colour, render.alpha, 9)
        return low, colour - low

    (low_s, _), (low_c, high_c), (low_g, high_g) = split(relit), split(albedo), split(near)
    expected = np.maximum(unpremultiply(relit) + detail_gain(low_s, low_g, "multiplicative") * high_g
                          - detail_gain(low_s, None, "ratio", low_c) * high_c, 0)
    np.testing.assert_allclose(frame.hybrid[inside], expected[inside], rtol=1e-4, atol=1e-5)
    same = compose(albedo, relit, filt, 9, detail="residual", far_capture=albedo)
    np.testing.assert_allclose(same.hybrid[inside], relit.color[inside], rtol=1e-5, atol=1e-6)
    ratio = compose(albedo, relit, filt, 9, detail="ratio", far_capture=albedo)
    assert np.abs(ratio.hybrid - relit.color)[inside].mean() > 0.05  # 'ratio' scales the capture's detail instead
    np.testing.assert_array_equal(compose(near, albedo, filt, 9, detail="residual").hybrid,
                                  compose(near, albedo, filt, 9, detail="multiplicative").hybrid)
    with pytest.raises(ValueError, match="needs h\\(S\\)"):
        hybrid_colour(high_g, low_g, low_s, "residual", low_c, None, high_c)


def test_same_light_compares_radiance_map_and_rotation():
    env = np.ones((4, 8, 3), np.float32)
    assert same_light(Light(np.ones(3)), Light(np.ones(3)))
    assert not same_light(Light(np.ones(3)), Light(np.ones(3) * 2))
    assert not same_light(Light(np.ones(3)), Light(np.ones(3), envmap=env))
    assert same_light(Light(np.ones(3), envmap=env, rotation_deg=90),
                      Light(np.ones(3), envmap=env.copy(), rotation_deg=90))
    assert not same_light(Light(np.ones(3), envmap=env), Light(np.ones(3), envmap=env, rotation_deg=90))
    assert not same_light(Light(np.ones(3), envmap=env), Light(np.ones(3), envmap=env * 0.5))


def hard_cases():
    h, w = 16, 20
    rng = np.random.default_rng(2)
    ones, zeros = np.ones((h, w), np.float32), np.zeros((h, w), np.float32)
    bright = rng.uniform(0.2, 1.0, (h, w, 3)).astype(np.float32)
    speck = np.full((h, w, 3), 1e-9, np.float32)
    speck[8, 10] = 1.0  # one bright texel in a near-black near field: l(G) tiny around it
    half = np.where(np.arange(w) < w // 2, 1.0, 0.0).astype(np.float32) * ones
    return {
        "alpha zero": (RenderOutput(bright * 0, zeros), RenderOutput(bright * 0, zeros)),
        "near alpha zero, far covered": (RenderOutput(bright * 0, zeros), RenderOutput(bright, ones)),
        "black far field": (RenderOutput(bright, ones), RenderOutput(bright * 0, ones)),
        "black near field": (RenderOutput(bright * 0, ones), RenderOutput(bright, ones)),
        "tiny denominators": (RenderOutput(speck, ones), RenderOutput(bright, ones)),
        "denormal near field": (RenderOutput(np.full((h, w, 3), 1e-40, np.float32), ones), RenderOutput(bright, ones)),
        "half covered": (RenderOutput(bright * half[..., None], half), RenderOutput(bright, ones)),
    }


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
@pytest.mark.parametrize("silhouette", ["near", "far"])
@pytest.mark.parametrize("detail", ["multiplicative", "ratio", "residual"])
@pytest.mark.parametrize("case", list(hard_cases()))
def test_guarded_hybrids_are_finite_and_bounded_on_hard_cases(filt, silhouette, detail, case):
    """The near field's render doubles as the capture-light far field of modes 'ratio' and 'residual' (their
    hard denominators)."""
    near, far = hard_cases()[case]
    frame = compose(near, far, filt, 7, silhouette=silhouette, outline_fade=1.0, detail=detail, far_capture=near)
    assert np.isfinite(frame.hybrid).all()
    # l(S) + g h(G) <= max l(S) + MAX_GAIN |h(G)|, with h(G) of un-premultiplied colours in [0, 1]; 'residual'
    # adds h(S) and takes g h(S_c) off: S + g (h(G) - h(S_c)) <= max S + 2 MAX_GAIN
    bound = frame.low_far.max() + MAX_GAIN if detail != "residual" else unpremultiply(far).max() + 2 * MAX_GAIN
    assert (frame.hybrid <= bound + 1e-5).all()
    assert (frame.hybrid >= 0).all()


def test_gain_is_the_guarded_ratio():
    low_near = np.array([0.0, 1e-40, GAIN_FLOOR / 2, 0.2, 0.2, 0.01], np.float32)
    low_far = np.array([0.5, 0.5, 0.0, 0.4, 0.0, 1.0], np.float32)
    gain = detail_gain(low_far, low_near, "multiplicative")
    expected = [min(0.5 / GAIN_FLOOR, MAX_GAIN), MAX_GAIN, 0.0, 2.0, 0.0, MAX_GAIN]
    np.testing.assert_allclose(gain, expected, rtol=1e-6)
    assert detail_gain(low_far, low_near, "additive") == 1.0
    assert detail_gain(low_far, low_near, "ratio") == 1.0  # no capture-light far field: the capture light
    np.testing.assert_allclose(detail_gain(low_far, np.ones(6), "ratio", low_near), expected, rtol=1e-6)
    with pytest.raises(ValueError, match="detail mode"):
        detail_gain(low_far, low_near, "divisive")


def test_render_settings_take_the_detail_mode_and_refuse_others():
    cfg = config_mod.resolve({"stages": {"render": {"detail": "multiplicative"}}})
    assert cfg.stage("render").detail == "multiplicative"
    assert config_mod.resolve({}).stage("render").detail == "multiplicative"
    with pytest.raises(PGCConfigError, match="detail"):
        config_mod.resolve({"stages": {"render": {"detail": "divisive"}}})
