"""The float64 per-pixel reference rasteriser against closed-form images."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.splats.projection import DILATION
from pgc.splats.reference import render_reference
from pgc.splats.sh import rgb_to_sh_dc
from pgc.types import Camera, WorldGaussians

F = 50.0


def _camera(w: int = 20, h: int = 16) -> Camera:
    return Camera(K=[[F, 0, w / 2], [0, F, h / 2], [0, 0, 1]], R=np.eye(3), t=np.zeros(3), width=w, height=h)


def _gaussians(means, scales, opacities, colors, quats=None) -> WorldGaussians:
    n = len(means)
    sh = np.zeros((n, 1, 3))
    sh[:, 0] = rgb_to_sh_dc(np.asarray(colors, float))
    q = np.tile([1.0, 0, 0, 0], (n, 1)) if quats is None else np.asarray(quats, float)
    return WorldGaussians(np.asarray(means, float), q, np.asarray(scales, float), np.asarray(opacities, float), sh)


def test_single_isotropic_gaussian_matches_closed_form():
    cam = _camera()
    z, s, o = 2.0, 0.02, 0.8
    out = render_reference(_gaussians([[0, 0, z]], [[s, s, s]], [o], [[0.9, 0.4, 0.1]]), cam)
    raw = (F * s / z) ** 2  # centre on the optical axis: J = diag(F/z)
    var = raw + DILATION
    ys, xs = np.mgrid[0:16, 0:20] + 0.5
    d2 = (xs - 10) ** 2 + (ys - 8) ** 2
    alpha = o * (raw / var) * np.exp(-0.5 * d2 / var)  # coverage sqrt(det ratio) = raw / var
    r = np.ceil(3 * np.sqrt(var))
    alpha[(np.abs(xs - 10) > r) | (np.abs(ys - 8) > r) | (alpha < 1 / 255)] = 0
    np.testing.assert_allclose(out.alpha, alpha, atol=1e-12)
    np.testing.assert_allclose(out.color, alpha[..., None] * [0.9, 0.4, 0.1], atol=1e-12)
    np.testing.assert_allclose(out.depth[alpha > 0], z)
    assert np.all(out.depth[alpha == 0] == 0)


@pytest.mark.parametrize("sigma_px", [0.6, 1.0, 2.0])
def test_the_pixel_filter_keeps_each_gaussians_mass(sigma_px):
    """The image-plane mass of a Gaussian (its alpha summed over pixels) is that of the Gaussian before the pixel
    filter, o 2 pi sigma^2, at every size: the coverage factor undoes the dilation's gain (3DGS's rule, dilation
    without it, would give o 2 pi (sigma^2 + DILATION): +28 % at 0.6 px). Within 2 %: the 3-sigma box and the
    1/255 cut drop under 1 %."""
    cam = _camera(40, 40)
    z, o = 2.0, 0.9
    s = sigma_px * z / F
    out = render_reference(_gaussians([[0, 0, z]], [[s, s, s]], [o], [[1.0, 1.0, 1.0]]), cam)
    np.testing.assert_allclose(out.alpha.sum(), o * 2 * np.pi * sigma_px ** 2, rtol=0.02)


def test_a_disc_seen_edge_on_covers_nothing():
    """A flat disc (third scale 0) whose plane holds the viewing ray has zero projected area: it draws nothing,
    where the dilation alone would paint a pixel-wide stroke."""
    cam = _camera()
    edge_on = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]  # the disc's normal (local z) turned onto the image y
    g = _gaussians([[0, 0, 2.0]], [[0.05, 0.05, 0.0]], [0.9], [[1, 1, 1]], quats=[edge_on])
    assert np.all(render_reference(g, cam).alpha == 0)
    face_on = render_reference(_gaussians([[0, 0, 2.0]], [[0.05, 0.05, 0.0]], [0.9], [[1, 1, 1]]), cam)
    assert face_on.alpha.max() > 0.7  # 0.9 x coverage 0.94 x the half-pixel offset of the centres


def test_front_to_back_order_alpha_cap_and_background():
    cam = _camera(4, 4)
    bg = np.array([0.1, 0.2, 0.3])
    g = _gaussians([[0, 0, 3.0], [0, 0, 2.0]], [[1.0] * 3] * 2, [0.5, 1.0], [[0, 0, 1], [1, 0, 0]])
    out = render_reference(g, cam, background=bg)
    a1 = 0.99 * np.ones((4, 4))  # the near one is capped at 0.99 and hides most of the far one
    np.testing.assert_allclose(out.alpha, 1 - (1 - a1) * (1 - 0.5 * np.exp(-0.5 * 0)), atol=2e-3)
    near_only = render_reference(_gaussians([[0, 0, 2.0]], [[1.0] * 3], [1.0], [[1, 0, 0]]), cam, background=bg)
    np.testing.assert_allclose(near_only.color[0, 0], 0.99 * np.array([1, 0, 0]) + 0.01 * bg, atol=1e-6)
    assert out.color[0, 0, 0] > out.color[0, 0, 2]


def test_transmittance_stops_at_threshold():
    cam = _camera(2, 2)
    n = 5  # five layers at alpha 0.99: the third would bring T to 1e-6 < 1e-4, so only two are composited
    g = _gaussians([[0, 0, 1.0 + i] for i in range(n)], [[10.0] * 3] * n, [1.0] * n, [[1, 1, 1]] * n)
    out = render_reference(g, cam)
    np.testing.assert_allclose(out.alpha, 1 - 0.01 ** 2)
    np.testing.assert_allclose(out.depth, (0.99 * 1 + 0.01 * 0.99 * 2) / (1 - 0.01 ** 2))


def test_behind_camera_and_empty_scenes_give_background():
    cam = _camera(6, 5)
    bg = np.random.default_rng(0).uniform(size=(5, 6, 3))
    behind = render_reference(_gaussians([[0, 0, -1.0], [0, 0, 0.005]], [[0.1] * 3] * 2, [1, 1], [[1, 1, 1]] * 2),
                              cam, background=bg)
    empty = render_reference(_gaussians(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))), cam,
                             background=bg)
    for out in (behind, empty):
        np.testing.assert_array_equal(out.alpha, 0)
        np.testing.assert_allclose(out.color, bg)
        np.testing.assert_array_equal(out.depth, 0)


def test_view_dependent_colour_uses_the_3dgs_sign_convention():
    cam = _camera(3, 3)
    g = _gaussians([[0, 0, 2.0]], [[1.0] * 3], [1.0], [[0.5, 0.5, 0.5]])
    g.sh = np.concatenate([g.sh, np.zeros((1, 3, 3))], axis=1)
    g.sh[0, 2] = 0.5  # coefficient of +C1 z: seen along +z, colour = 0.5 + C1 * 0.5
    out = render_reference(g, cam)
    np.testing.assert_allclose(out.color[1, 1], 0.99 * (0.5 + 0.4886025119029199 * 0.5), rtol=1e-9)
    np.testing.assert_allclose(render_reference(g, cam, sh_degree=0).color[1, 1], 0.99 * 0.5, rtol=1e-9)


def test_bad_background_shape_is_an_error():
    with pytest.raises(ValueError, match="background"):
        render_reference(_gaussians([[0, 0, 1.0]], [[1.0] * 3], [1.0], [[1, 1, 1]]), _camera(3, 3),
                         background=np.zeros((2, 2, 3)))
