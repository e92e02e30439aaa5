"""Hybrid composition: the identities of h(G) + l(S), Gaussian UV lookups, far-field recolouring."""

import numpy as np
import pytest

from pgc.pipeline.compose import compose, far_field_gaussians, gaussian_uvs, unpremultiply
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
