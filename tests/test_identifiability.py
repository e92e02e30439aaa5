"""The identifiability study of pgc.brdfs.identifiability: its Jacobian against finite differences (float64), the
exact null space it must find, and the lighting comparison measured in docs/pbr.md."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pgc.brdfs import identifiability as ident  # noqa: E402
from pgc.sampling import fibonacci_sphere  # noqa: E402

COTTON = ((0.70, 0.69, 0.66), (0.03, 0.05, 0.16), (0.62, 0.05, 0.04))


@pytest.fixture(scope="module")
def scene():
    return ident.study_scene(COTTON, n_points=40, n_views=6)


def _theta():
    return ident.parameter_vector([0.9, 1.0, 1.1], [1.2, 1.0, 0.8], 0.9, [0.06, 0.05, 0.07], 0.6)


def test_jacobian_matches_central_differences():
    scene = ident.study_scene(COTTON, n_points=24, n_views=4)
    frames = [ident.uniform_frame(16), ident.sky_sun_frame(16), *ident.key_light_frames()[:1]]
    theta = _theta()
    J = ident.jacobian(scene, frames, theta)
    assert J.shape == (3 * len(frames) * len(scene.pairs[0]), len(ident.PARAMETER_NAMES))
    assert np.isfinite(J).all()
    for i in range(len(theta)):
        h = 1e-6 * abs(theta[i])
        e = np.zeros_like(theta)
        e[i] = h
        fd = (ident.render(scene, frames, torch.tensor(theta + e)).numpy()
              - ident.render(scene, frames, torch.tensor(theta - e)).numpy()) / (2 * h)
        scale = np.abs(J[:, i]).max()
        assert scale > 0, ident.PARAMETER_NAMES[i]
        np.testing.assert_allclose(J[:, i], fd, rtol=0, atol=1e-7 * scale, err_msg=ident.PARAMETER_NAMES[i])


@pytest.mark.parametrize("light", ["uniform", "sky+sun", "uniform+4 keys"])
def test_base_light_sheen_scale_is_an_exact_null_space(scene, light):
    """pixel_c = light_c (base_c D + sheen_c S): scaling base_c and sheen_c by (1 + e) and light_c by 1 / (1 + e)
    changes nothing, under any lighting: three zero singular values when all 11 parameters are free."""
    theta = _theta()
    J = ident.jacobian(scene, ident.lightings(32)[light], theta)
    a = ident.analyse(J, theta, ident.PARAMETER_NAMES, noise=0.01)
    assert np.all(a.singular_values[-3:] < 1e-12 * a.singular_values[0])
    assert a.singular_values[-4] > 1e-4 * a.singular_values[0]
    assert not np.isfinite(a.relative_std[ident.PARAMETER_NAMES.index("sheen_r")])
    # the fit's set (texture given) has no null direction
    fit = ident.analyse(J, theta, ident.FIT_PARAMETERS, noise=0.01)
    assert fit.singular_values[-1] > 1e-4 * fit.singular_values[0]
    assert np.isfinite(fit.relative_std).all()


FLEECE = ((0.10, 0.20, 0.11), (0.16, 0.27, 0.15))


def test_sky_and_sun_identifies_the_fleece_far_better_than_uniform_light():
    """On the fleece control the weakest direction of the fit's parameters (roughness against sheen colour)
    has a singular value 3.3-6.3x larger under sky + sun than under the uniform environment (measured: 3.3x on
    this 60-point, 8-view patch with 32 directions, 6.3x in docs/pbr.md's 300-point study); asserted at 2.5x."""
    scene = ident.study_scene(FLEECE, n_points=60, n_views=8)
    theta = ident.parameter_vector([1, 1, 1], [1, 1, 1], 0.8, [0.35, 0.36, 0.35], 0.45)
    sigma = {}
    for light in ("uniform", "sky+sun"):
        J = ident.jacobian(scene, ident.lightings(32)[light], theta)
        sigma[light] = ident.analyse(J, theta, ident.FIT_PARAMETERS, noise=0.01).singular_values[-1]
    assert sigma["sky+sun"] > 2.5 * sigma["uniform"], sigma


def test_tangent_frame_is_orthonormal_and_right_handed():
    from pgc.arrays import array_ops
    from pgc.brdfs.maths import tangent_frame

    n = fibonacci_sphere(200)
    n = np.concatenate([n, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]])
    t, b = tangent_frame(array_ops("numpy"), n)
    for u, v in ((t, b), (t, n), (b, n)):
        np.testing.assert_allclose((u * v).sum(-1), 0.0, atol=1e-12)
    for u in (t, b):
        np.testing.assert_allclose(np.linalg.norm(u, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)
