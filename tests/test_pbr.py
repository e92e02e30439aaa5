"""PBR renderers (role ``pbr_renderer``): analytic radiance, texture space against screen space, the fast
torch approximation against the path tracer (constant and environment light), and input errors."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pgc.testing.pbr_scenes import checker_texture, folded_sheet, ring_cameras, uv_sphere
from pgc.errors import PGCDataError
from pgc.registry import default_registry
from pgc.texture.atlas import texel_geometry
from pgc.texture.sample import sample_bilinear
from pgc.texture.visibility import render_faces, visible_points
from pgc.types import Light, Material, Mesh

pytest.importorskip("mitsuba")
SHEEN = {"roughness": 0.6, "sheen_color": [0.7, 0.6, 0.4], "sheen_roughness": 0.3}


@pytest.fixture(scope="module")
def mitsuba_renderer():
    return default_registry().create("pbr_renderer", "mitsuba", {"spp": 64})


@pytest.fixture(scope="module")
def torch_renderer():
    pytest.importorskip("open3d")
    return default_registry().create("pbr_renderer", "torch", {"directions": 512, "threads": 1})


def _envmap(size: int = 16) -> np.ndarray:
    """A lat-long map: bright warm sky patch toward +X and up, dim blue elsewhere."""
    h, w = size, 2 * size
    env = np.tile(np.array([0.1, 0.15, 0.3], np.float32), (h, w, 1))
    env[: h // 2, w // 4: w // 2] = [3.0, 2.5, 1.5]
    return env


def test_lambertian_sphere_matches_analytic(mitsuba_renderer, torch_renderer) -> None:
    """A convex Lambertian sphere in a constant environment E reflects exactly albedo * E everywhere."""
    sphere = uv_sphere(n_lat=24, n_lon=48)
    mat = Material("lambertian", {"base_color": [0.6, 0.4, 0.2]})
    light = Light(np.array([2.0, 1.5, 1.0]))
    cam = ring_cameras(1, size=40, radius=2.0)[0]
    expected = np.array([0.6, 0.4, 0.2]) * light.radiance
    for renderer, tol in ((mitsuba_renderer, 0.02), (torch_renderer, 0.01)):
        out = renderer.render(sphere, mat, light, cam)
        interior = out.alpha > 0.999
        assert interior.sum() > 200
        np.testing.assert_allclose(np.median(out.color[interior], axis=0), expected, rtol=tol)
        assert np.all(np.isfinite(out.color)) and out.alpha.min() >= 0 and out.alpha.max() <= 1


def _texture_vs_screen(renderer, mesh: Mesh, material: Material, light: Light, cam, res: int):
    """Texel radiance and the screen image at the texel's projection, for texels seen squarely."""
    screen = renderer.render(mesh, material, light, cam)
    tex, cover = renderer.render_texture(mesh, material, light, cam, (res, res))
    geom = texel_geometry(mesh, res, res)
    valid = geom.valid & (cover > 0.99)
    pts, faces = geom.position[valid], geom.face[valid]
    seen, xy = visible_points(pts, faces, render_faces(mesh, cam), cam)
    to_cam = cam.center - pts
    cos = np.abs(np.sum(geom.normal[valid] * to_cam, axis=1)) / np.linalg.norm(to_cam, axis=1)
    # the 3x3 pixel neighbourhood of the projection is fully covered (no silhouette mixing)
    full = np.ones(len(pts), bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            q = np.clip((xy + [dx, dy]).astype(int), 0, [cam.width - 1, cam.height - 1])
            full &= screen.alpha[q[:, 1], q[:, 0]] > 0.999
    keep = seen & (cos > 0.3) & full
    assert keep.sum() > 100
    return tex[valid][keep], sample_bilinear(screen.color, xy[keep] - 0.5)


@pytest.mark.parametrize("name", ["mitsuba", "torch"])
def test_texture_space_agrees_with_screen_space(name, mitsuba_renderer, torch_renderer) -> None:
    """Where a texel is visible, its texture-space radiance toward the camera is the screen radiance at its
    projection (folded sheet: self-shadowing and inter-reflection; sheen: view dependence)."""
    renderer = mitsuba_renderer if name == "mitsuba" else torch_renderer
    mesh = folded_sheet(n=24)
    mat = Material("pgc-sheen", dict(SHEEN, base_color=[0.5, 0.4, 0.3]))
    light = Light(np.array([1.5, 1.4, 1.2]))
    cam = ring_cameras(3, size=64, radius=1.8, arc_deg=100, elevation_deg=10)[0]
    texel, pixel = _texture_vs_screen(renderer, mesh, mat, light, cam, 48)
    rel = np.abs(texel - pixel).mean(1) / pixel.mean(1)
    assert np.median(rel) < (0.05 if name == "mitsuba" else 0.02)  # Monte Carlo noise at 64 spp (measured 0.034)
    assert abs(texel.mean() / pixel.mean() - 1) < 0.01  # no bias


@pytest.mark.parametrize("use_envmap", [False, True])
def test_torch_approximation_close_to_path_tracer(use_envmap, mitsuba_renderer, torch_renderer) -> None:
    """Same scene, same conventions (environment orientation and rotation included): the fast renderer's
    image is within a few percent of the path-traced one."""
    mesh = folded_sheet(n=24)
    mat = Material("pgc-sheen", dict(SHEEN), checker_texture(32))
    light = Light(np.array([1.0, 1.0, 1.0]), envmap=_envmap() if use_envmap else None, rotation_deg=35.0)
    cam = ring_cameras(3, size=48, radius=1.8, arc_deg=100, elevation_deg=20)[1]
    a = mitsuba_renderer.render(mesh, mat, light, cam, spp=256)
    b = torch_renderer.render(mesh, mat, light, cam)
    both = (a.alpha > 0.999) & (b.alpha > 0)
    assert abs(b.color[both].mean() / a.color[both].mean() - 1) < 0.04
    assert np.abs(a.color[both] - b.color[both]).mean() / a.color[both].mean() < 0.12


def test_envmap_rotation_is_about_plus_y(torch_renderer) -> None:
    """Rotating the environment by 360 degrees changes nothing; by 180 degrees it changes the image."""
    mesh = uv_sphere(n_lat=16, n_lon=32)
    mat = Material("lambertian", {"base_color": [0.5, 0.5, 0.5]})
    cam = ring_cameras(1, size=32, radius=2.0)[0]
    imgs = [torch_renderer.render(mesh, mat, Light(np.ones(3), _envmap(), r), cam).color for r in (0.0, 360.0, 180.0)]
    np.testing.assert_allclose(imgs[0], imgs[1], atol=1e-5)
    assert np.abs(imgs[0] - imgs[2]).mean() > 0.05


def test_texture_space_coverage_and_errors(mitsuba_renderer, torch_renderer) -> None:
    mesh = folded_sheet(n=8)
    mat = Material("lambertian", {"base_color": [0.5, 0.5, 0.5]})
    cam = ring_cameras(1, size=16)[0]
    for renderer in (mitsuba_renderer, torch_renderer):
        tex, cover = renderer.render_texture(mesh, mat, Light(np.ones(3)), cam, (16, 16))
        assert tex.shape == (16, 16, 3) and cover.shape == (16, 16) and np.all(np.isfinite(tex))
        assert cover.min() >= 0 and cover.mean() > 0.9  # the sheet's atlas fills [0, 1]^2
        no_uv = Mesh(mesh.vertices, mesh.faces)
        with pytest.raises(PGCDataError, match="UV"):
            renderer.render_texture(no_uv, mat, Light(np.ones(3)), cam, (8, 8))
        with pytest.raises(PGCDataError, match="base_color"):
            renderer.render(mesh, Material("lambertian"), Light(np.ones(3)), cam)
    with pytest.raises(PGCDataError, match="radiance"):
        mitsuba_renderer.render(mesh, mat, Light(np.array([1.0, -1.0, 1.0])), cam)
    with pytest.raises(PGCDataError, match="envmap"):
        mitsuba_renderer.render(mesh, mat, Light(np.ones(3), envmap=np.ones((4, 4, 3), np.float32)), cam)


def test_an_occluder_hides_and_shadows_but_is_not_rendered(mitsuba_renderer, torch_renderer) -> None:
    """A small sphere between the camera and a big one: its pixels are empty (colour and alpha 0), the big
    sphere is darker where the small one blocks part of its sky, and it is unchanged far from it."""
    from scipy.ndimage import binary_dilation

    big = uv_sphere(n_lat=24, n_lon=48)
    small = Mesh(uv_sphere(n_lat=12, n_lon=24).vertices * 0.3, uv_sphere(n_lat=12, n_lon=24).faces, name="occluder")
    cam = ring_cameras(1, size=40, radius=2.0)[0]
    small = Mesh(small.vertices + 0.55 * (cam.center / np.linalg.norm(cam.center)), small.faces, name="occluder")
    mat = Material("lambertian", {"base_color": [0.6, 0.6, 0.6]})
    light = Light(np.ones(3))
    hidden = render_faces(big, cam, occluder=small).face_id < 0
    alone_cover = render_faces(big, cam).face_id >= 0
    in_front = alone_cover & hidden
    assert in_front.sum() > 20
    for renderer in (mitsuba_renderer, torch_renderer):
        plain = renderer.render(big, mat, light, cam)
        out = renderer.render(big, mat, light, cam, occluder=small)
        assert np.all(out.color[in_front] == 0) and np.all(out.alpha[in_front] == 0)
        ring = alone_cover & ~hidden & binary_dilation(in_front, iterations=3)
        far = (out.alpha > 0.999) & (np.abs(np.indices(hidden.shape) - 20).max(0) >= 15)
        assert ring.sum() > 10 and far.sum() > 10
        assert out.color[ring].mean() < 0.97 * plain.color[ring].mean()  # shadowed around the occluder
        np.testing.assert_allclose(out.color[far].mean(0), plain.color[far].mean(0), rtol=0.05)


def test_mitsuba_reuses_its_scene_only_for_equal_inputs() -> None:
    """Rendering the same inputs from another camera reuses the scene and gives the images of a fresh
    renderer; a changed input (an array edited in place included) builds a new scene."""
    reg = default_registry()
    reused = reg.create("pbr_renderer", "mitsuba", {"spp": 8})
    sphere = uv_sphere(n_lat=12, n_lon=24)
    mat = Material("pgc-sheen", {"base_color": [0.5, 0.4, 0.3], **SHEEN})
    light = Light(np.ones(3))
    cams = ring_cameras(2, size=24, radius=2.0)
    first = reused.render(sphere, mat, light, cams[0])
    scene = reused._last_scene[1]
    second = reused.render(replace(sphere, vertices=sphere.vertices.copy()), mat, light, cams[1])
    assert reused._last_scene[1] is scene
    for cam, out in zip(cams, (first, second)):
        fresh = reg.create("pbr_renderer", "mitsuba", {"spp": 8}).render(sphere, mat, light, cam)
        assert np.array_equal(out.color, fresh.color) and np.array_equal(out.alpha, fresh.alpha)
    moved = sphere.vertices.copy()
    reused.render(replace(sphere, vertices=moved), mat, light, cams[0])
    assert reused._last_scene[1] is scene
    moved *= 0.5  # in place: the renderer must notice
    small = reused.render(replace(sphere, vertices=moved), mat, light, cams[0])
    assert reused._last_scene[1] is not scene and small.alpha.sum() < 0.5 * first.alpha.sum()
    brighter = reused.render(sphere, mat, Light(2 * np.ones(3)), cams[0])
    assert brighter.color.sum() > 1.5 * first.color.sum()
