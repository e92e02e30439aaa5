"""Texture space: rasterisation, atlas geometry, back-projection round trip, colour correction."""

import numpy as np
import pytest

from pgc.texture.atlas import texel_geometry
from pgc.texture.backproject import fill_holes, merge_views, project_view
from pgc.texture.color_correction import apply_color_matrix, fit_color_matrix
from pgc.texture.visibility import render_faces, render_texture_to_view
from pgc.types import Camera, Mesh


def look_at(center, target, width=64, height=64, f=80.0, name="c"):
    center, target = np.asarray(center, float), np.asarray(target, float)
    z = target - center
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 1.0, 0.0])
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    K = np.array([[f, 0, width / 2], [0, f, height / 2], [0, 0, 1]])
    return Camera(K, R, -R @ center, width, height, name=name)


def quad_mesh():
    """A unit square in the z=0 plane facing +z, UVs covering the whole atlas."""
    v = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy(), np.array([2, 2]))


def test_texel_geometry_positions_lie_on_the_quad():
    geom = texel_geometry(quad_mesh(), 16, 16)
    assert geom.valid.all()
    # texel (row 0, col 0) is the top-left: u = 1/32, v = 1 - 1/32 -> x = -0.5 + 1/32, y = 0.5 - 1/32
    np.testing.assert_allclose(geom.position[0, 0], [-0.5 + 1 / 32, 0.5 - 1 / 32, 0], atol=1e-12)
    np.testing.assert_allclose(geom.normal[5, 7], [0, 0, 1])


def test_render_faces_depth_matches_plane_distance():
    cam = look_at([0, 0, 2.0], [0, 0, 0])
    r = render_faces(quad_mesh(), cam)
    assert (r.face_id >= 0).sum() > 0.5 * 40 * 40
    np.testing.assert_allclose(r.depth[r.face_id >= 0], 2.0, atol=1e-9)


def test_backprojection_round_trip_returns_the_texture():
    rng = np.random.default_rng(0)
    mesh = quad_mesh()
    texture = np.repeat(np.repeat(rng.uniform(0.1, 0.9, (8, 8, 3)), 4, 0), 4, 1).astype(np.float32)
    geom = texel_geometry(mesh, 32, 32)
    views = []
    for k, c in enumerate([[0, 0, 1.5], [0.4, 0.2, 1.4], [-0.3, -0.4, 1.4]]):
        cam = look_at(c, [0, 0, 0], 96, 96, f=160.0, name=str(k))
        img, cov = render_texture_to_view(mesh, texture, cam)
        views.append(project_view(geom, mesh, cam, img, cov))
    merged, weight = merge_views(views, "median")
    seen = weight > 0
    assert seen.mean() > 0.9
    # Away from the 4x4 blocks' borders the back-projected colours equal the texture.
    inner = np.zeros((32, 32), bool)
    inner[1::4, 1::4] = inner[2::4, 2::4] = True
    sel = seen & inner
    np.testing.assert_allclose(merged[sel], texture[sel], atol=2e-2)


def test_fill_holes_keeps_known_texels_and_is_finite():
    tex = np.zeros((16, 16, 3), np.float32)
    known = np.zeros((16, 16), bool)
    known[4:8, 4:8] = True
    tex[known] = [0.2, 0.4, 0.6]
    out = fill_holes(tex, known)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, np.broadcast_to([0.2, 0.4, 0.6], out.shape), atol=1e-6)
    assert np.all(fill_holes(tex, np.zeros_like(known)) == 0)


def test_color_matrix_recovers_known_matrix_with_outliers():
    rng = np.random.default_rng(1)
    m_true = np.array([[0.9, 0.1, 0.0], [0.05, 1.1, 0.02], [0.0, -0.1, 0.8]])
    src = rng.uniform(0, 1, (2000, 3))
    dst = src @ m_true.T + rng.normal(0, 1e-3, (2000, 3))
    dst[:100] = rng.uniform(0, 1, (100, 3))  # 5 % outliers
    m = fit_color_matrix(src, dst)
    np.testing.assert_allclose(m, m_true, atol=5e-3)
    np.testing.assert_allclose(apply_color_matrix(src[100:110], m), dst[100:110], atol=2e-2)


@pytest.mark.parametrize("n", [0, 1, 2])
def test_color_matrix_with_too_few_pairs_is_finite(n):
    m = fit_color_matrix(np.ones((n, 3)) * 0.5, np.ones((n, 3)) * 0.25)
    assert np.all(np.isfinite(m))


def test_color_matrix_stays_well_conditioned_for_nearly_collinear_colours():
    """A garment of two colours (grey and navy stripes) determines only part of M: the ridge keeps the
    rest at the per-channel fit instead of letting cross terms explode."""
    rng = np.random.default_rng(4)
    palette = np.array([[0.5, 0.5, 0.48], [0.02, 0.03, 0.15]])
    src = palette[rng.integers(0, 2, 3000)] + rng.normal(0, 2e-3, (3000, 3))
    dst = src * np.array([1.2, 1.1, 0.9])
    m = fit_color_matrix(src, dst)
    assert np.linalg.cond(m) < 10
    np.testing.assert_allclose(apply_color_matrix(src, m), dst, atol=5e-3)


def test_colour_correction_removes_per_view_casts_from_the_cross_view_spread():
    """Views of one texture through different camera casts (per-channel gains) disagree; fitting each to
    the consensus brings the spread back to that of the noise alone."""
    from pgc.albedo.base_color import cross_view_spread
    from pgc.texture.backproject import ViewTexture

    rng = np.random.default_rng(2)
    albedo = rng.uniform(0.1, 0.9, (32, 32, 3))
    weight = np.ones((32, 32), np.float32)
    clean = [albedo * (1 + rng.normal(0, 0.01, albedo.shape)) for _ in range(6)]
    cast = [c * rng.uniform(0.7, 1.3, 3) for c in clean]
    views = [ViewTexture(c.astype(np.float32), weight) for c in cast]
    consensus, seen = merge_views(views, "median")
    corrected = [ViewTexture(apply_color_matrix(v.color, fit_color_matrix(v.color, consensus, v.weight)), weight)
                 for v in views]
    noise_only = cross_view_spread([ViewTexture(c.astype(np.float32), weight) for c in clean])
    assert cross_view_spread(views) > 5 * noise_only
    assert cross_view_spread(corrected) < 1.2 * noise_only
