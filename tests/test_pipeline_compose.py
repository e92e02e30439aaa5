"""Hybrid composition: the identities of h(G) + l(S), Gaussian UV lookups, far-field recolouring."""

import numpy as np
import pytest

from pgc.pipeline.compose import compose, far_field_gaussians, gaussian_uvs, outline_weight, unpremultiply
from pgc.registry import default_registry
from pgc.roles.splat_renderer import RenderOutput
from pgc.splats.init import sample_on_mesh
from pgc.splats.sh import sh_to_rgb_dc
from pgc.types import Mesh


def quad():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy())


def filters():
    reg = default_registry()
    return [reg.create("filter", name) for name in ("torch", "opencv", "jax")
            if ("filter", name) in reg.implementations and reg.get("filter", name).available]


def random_render(rng, h=24, w=32):
    alpha = np.clip(rng.uniform(-0.3, 1.2, (h, w)), 0, 1).astype(np.float32)
    color = (rng.uniform(0, 1, (h, w, 3)) * alpha[..., None]).astype(np.float32)
    return RenderOutput(color, alpha)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_identical_near_and_far_fields_compose_to_the_near_field(filt):
    rng = np.random.default_rng(0)
    g = random_render(rng)
    frame = compose(g, g, filt, 7)
    np.testing.assert_allclose(frame.hybrid, g.color, atol=1e-5)
    np.testing.assert_allclose(frame.high_near + frame.low_far, unpremultiply(g), atol=1e-5)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_error_decomposition_holds(filt):
    """I - I_t = (l(G) - l(S)) + (I - G) on un-premultiplied colours, for any reference I."""
    rng = np.random.default_rng(1)
    g, s = random_render(rng), random_render(rng)
    s = RenderOutput(s.color, g.alpha.copy())
    s.color = unpremultiply(RenderOutput(s.color, s.alpha)) * g.alpha[..., None]
    frame = compose(g, s, filt, 9)
    ref = rng.uniform(0, 1, g.color.shape).astype(np.float32)
    hybrid = frame.high_near + frame.low_far
    lhs = ref - hybrid
    rhs = (filt.lowpass(unpremultiply(g), g.alpha, 9) - frame.low_far) + (ref - unpremultiply(g))
    np.testing.assert_allclose(lhs, rhs, atol=1e-5)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_far_silhouette_takes_the_far_fields_shape_and_fades_the_detail_with_the_near_alpha(filt):
    rng = np.random.default_rng(2)
    h, w = 24, 32
    far_alpha = np.zeros((h, w), np.float32)
    far_alpha[4:20, 6:26] = 1.0  # the mesh's coverage: a rectangle
    near_alpha = np.zeros((h, w), np.float32)
    near_alpha[2:22, 4:18] = 1.0  # the splats: wider on the left, missing on the right
    far = RenderOutput((rng.uniform(0, 1, (h, w, 3)) * far_alpha[..., None]).astype(np.float32), far_alpha)
    near = RenderOutput((rng.uniform(0, 1, (h, w, 3)) * near_alpha[..., None]).astype(np.float32), near_alpha)
    background = np.array([0.1, 0.7, 0.3], np.float32)
    frame = compose(near, far, filt, 7, background=background, silhouette="far")
    np.testing.assert_array_equal(frame.hybrid_alpha, far_alpha)
    np.testing.assert_array_equal(frame.alpha, near_alpha)
    outside = far_alpha == 0  # background there, even where the splats cover
    np.testing.assert_allclose(frame.hybrid[outside], np.broadcast_to(background, frame.hybrid[outside].shape))
    only_far = (far_alpha == 1) & (near_alpha == 0)  # no near-field detail where the splats do not cover
    np.testing.assert_allclose(frame.hybrid[only_far], np.clip(frame.low_far[only_far], 0, None), atol=1e-6)
    both = (far_alpha == 1) & (near_alpha == 1)
    np.testing.assert_allclose(frame.hybrid[both], np.clip(frame.low_far + frame.high_near, 0, None)[both],
                               atol=1e-6)
    near_shape = compose(near, far, filt, 7, background=background, silhouette="near")
    np.testing.assert_array_equal(near_shape.hybrid_alpha, near_alpha)
    np.testing.assert_allclose(near_shape.hybrid[both], frame.hybrid[both], atol=1e-6)
    with pytest.raises(ValueError, match="silhouette"):
        compose(near, far, filt, 7, silhouette="mesh")


def test_outline_weight_is_the_distance_into_the_shape_over_the_width():
    alpha = np.zeros((12, 20), np.float32)
    alpha[2:10, 3:17] = 1.0  # 8 x 14 px
    w = outline_weight(alpha, 3.0)
    assert np.all(w[alpha == 0] == 0)
    np.testing.assert_allclose(w[5, 3:9], [0.5 / 3, 1.5 / 3, 2.5 / 3, 1.0, 1.0, 1.0], atol=1e-6)  # from the left edge
    np.testing.assert_allclose(w[2, 8], 0.5 / 3, atol=1e-6)  # the top row: half a pixel from the outline
    assert np.all(outline_weight(alpha, 0.0) == 1) and outline_weight(alpha, 3.0).dtype == np.float32
    assert np.all(np.isfinite(outline_weight(np.zeros((4, 4)), 2.0)))  # nothing covered: all zero
    assert np.all(outline_weight(np.ones((4, 4)), 2.0) == 1)  # everything covered: no outline
    edge = np.zeros((6, 6), np.float32)
    edge[:, :4] = 1.0  # cut by the image's left border: only the right side is an outline
    np.testing.assert_allclose(outline_weight(edge, 2.0)[2], [1, 1, 0.75, 0.25, 0, 0], atol=1e-6)


@pytest.mark.parametrize("filt", filters(), ids=lambda f: type(f).__name__)
def test_outline_fade_blends_the_hybrid_into_the_far_field_at_its_outline(filt):
    """hybrid = S + w (l(S) + a h(G) - S) with w the outline weight over fade x kernel px: the far field itself
    on the outline's first pixels, the unfaded hybrid deeper inside than the band, and the same alpha."""
    rng = np.random.default_rng(3)
    h, w, k = 32, 40, 5
    far_alpha = np.zeros((h, w), np.float32)
    far_alpha[4:28, 4:36] = 1.0
    near_alpha = np.ones((h, w), np.float32)
    far = RenderOutput((rng.uniform(0, 1, (h, w, 3)) * far_alpha[..., None]).astype(np.float32), far_alpha)
    near = RenderOutput(rng.uniform(0, 1, (h, w, 3)).astype(np.float32), near_alpha)
    plain = compose(near, far, filt, k, silhouette="far")
    faded = compose(near, far, filt, k, silhouette="far", outline_fade=1.0)
    np.testing.assert_array_equal(faded.hybrid_alpha, plain.hybrid_alpha)
    weight = outline_weight(far_alpha, 1.0 * k)[..., None]
    s = unpremultiply(far)
    expected = np.clip(s + weight * (plain.low_far + plain.high_near - s), 0, None) * far_alpha[..., None]
    np.testing.assert_allclose(faded.hybrid, expected, atol=1e-5)
    deep = weight[..., 0] == 1
    np.testing.assert_allclose(faded.hybrid[deep], plain.hybrid[deep], atol=1e-6)
    np.testing.assert_allclose(faded.hybrid[4, 10], s[4, 10] + (0.5 / k) * (plain.hybrid[4, 10] - s[4, 10]),
                               atol=1e-5)
    near_shape = compose(near, far, filt, k, silhouette="near", outline_fade=1.0)  # no fade with the near alpha
    np.testing.assert_array_equal(near_shape.hybrid, compose(near, far, filt, k, silhouette="near").hybrid)


def test_eval_reads_each_variants_own_alpha_and_older_runs_still_evaluate():
    from pgc.pipeline.evaluate import layer_alpha

    frame = {"alpha": 0, "pbr_alpha": 0, "hybrid_alpha": 0}
    assert [layer_alpha(k, frame) for k in ("hybrid", "near", "pbr")] == ["hybrid_alpha", "alpha", "pbr_alpha"]
    older = {"alpha": 0, "pbr_alpha": 0}  # rendered when the hybrid always took the near field's alpha
    assert layer_alpha("hybrid", older) == "alpha"


def test_gaussian_uvs_of_centred_gaussians_are_the_face_centroid_uvs():
    mesh = quad()
    g = sample_on_mesh(mesh, 50, np.random.default_rng(0), sh_degree=0)
    g.means[:] = 0.0  # the centroid of the parent face
    uv = gaussian_uvs(g, mesh)
    expect = mesh.uv[mesh.face_uv[g.parent]].mean(axis=1)
    np.testing.assert_allclose(uv, expect, atol=1e-6)


def test_far_field_colours_come_from_the_texture_as_dc_only():
    mesh = quad()
    g = sample_on_mesh(mesh, 20, np.random.default_rng(0), sh_degree=2)
    texture = np.zeros((8, 8, 3), np.float32)
    texture[...] = [0.2, 0.5, 0.9]
    far = far_field_gaussians(g, gaussian_uvs(g, mesh), texture)
    assert far.sh.shape == (20, 1, 3)
    np.testing.assert_allclose(sh_to_rgb_dc(far.sh[:, 0]), np.broadcast_to([0.2, 0.5, 0.9], (20, 3)), atol=1e-6)
    np.testing.assert_array_equal(far.means, g.means)
