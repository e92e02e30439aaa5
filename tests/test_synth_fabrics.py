"""Fabric textures, the weave normal map, fibres, and the dome rig."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.synth import fabrics, rig
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.types import Mesh


def quad(size: float = 0.2) -> Mesh:
    v = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy(), np.full(2, 2, np.int32))


def test_texel_positions_interpolate_the_surface():
    m = quad(0.2)
    pos, covered = fabrics.texel_positions(m, 16)
    assert covered.all()
    # texel (row r, col c) centre is uv ((c + 0.5) / 16, 1 - (r + 0.5) / 16) -> position 0.2 * uv
    r, c = 3, 11
    np.testing.assert_allclose(pos[r, c], [0.2 * (c + 0.5) / 16, 0.2 * (1 - (r + 0.5) / 16), 0], atol=1e-12)
    assert fabrics.texel_size(m, 16) == pytest.approx(0.2 / 16)


@pytest.mark.parametrize("name", list(fabrics.FABRICS))
def test_fabric_textures_are_valid(name):
    fab = fabrics.FABRICS[name]
    material, normal_map = fabrics.make_material(fab, quad(0.3), 64, seed=3)
    tex = material.base_color
    assert tex.shape == (64, 64, 3) and np.all(np.isfinite(tex)) and tex.min() >= 0 and tex.max() <= 1
    assert material.brdf == fab.brdf and set(material.params) == set(fab.params)
    if fab.pattern.startswith(("stripes", "checks", "knit")):
        assert tex.std(axis=(0, 1)).max() > 0.02  # a visible pattern
    if normal_map is None:
        assert fab.weave_depth == 0
    else:
        n = normal_map * 2 - 1
        np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-5)
        assert n[..., 2].min() > 0.5 and n[..., :2].std() > 0.05


def test_fibres_ride_on_the_garment():
    m = quad(0.3)
    fab = fabrics.FABRICS["fleece-sheen"]
    material, _ = fabrics.make_material(fab, m, 32, seed=0)
    fib = fabrics.make_fibres(fab, m, material, seed=0, scale=100.0)
    pts = fib.control_points(m.vertices, m.faces)
    assert pts.shape == (len(fib.face), 3, 3)
    np.testing.assert_allclose(pts[:, 0, 2], 0, atol=1e-12)  # rooted on the plane z = 0 ...
    assert np.all(pts[:, 1:, 2] > 0)  # ... standing off its front side (normal +z)
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1).sum(axis=1)
    np.testing.assert_allclose(seg, fab.fibre_length, rtol=1e-9)
    R, t = axis_angle_to_matrix(np.array([0.4, -0.2, 1.0])), np.array([0.1, 2.0, -0.3])
    moved = fib.control_points(m.vertices @ R.T + t, m.faces)
    np.testing.assert_allclose(moved, pts @ R.T + t, atol=1e-12)  # they follow any rigid motion exactly
    assert fabrics.make_fibres(fabrics.FABRICS["cotton-sheen"], m, material, seed=0) is None


def test_dome_cameras_look_at_the_subject():
    cams = rig.dome_cameras(32, 256, 192, center=(0, 0.85, 0), distance=2.6, subject_radius=0.88)
    assert len(cams) == 32 and len({c.name for c in cams}) == 32
    for c in cams:
        uv, z = c.project(np.array([[0, 0.85, 0.0]]))
        np.testing.assert_allclose(uv[0], [128, 96], atol=1e-6)  # the centre projects to the image centre
        assert z[0] == pytest.approx(2.6)
        np.testing.assert_allclose(c.R @ c.R.T, np.eye(3), atol=1e-12)
        assert c.R[1] @ [0, 1, 0] < 0  # image y (down) points against world up
    heights = np.array([c.center[1] for c in cams])
    assert heights.min() < 0.85 < heights.max()  # rings below and above the subject's centre


def test_garment_framing_zooms_onto_the_garment_and_keeps_it_in_every_view():
    from pgc.synth.generate import framing_sphere

    rng = np.random.default_rng(0)
    height = 1.7
    garment = rng.uniform([-0.35, 0.8, -0.15], [0.35, 1.5, 0.15], (500, 3))  # a torso-sized cloud
    spans = {}
    for framing in ("body", "garment"):
        center, radius = framing_sphere(framing, height, garment)
        cams = rig.dome_cameras(16, 128, 128, center=center, distance=1.55 * height, subject_radius=radius)
        spans[framing] = []
        for c in cams:
            uv, z = c.project(garment)
            assert np.all(z > 0) and np.all((uv > 0) & (uv < 128))  # every vertex in every view
            spans[framing].append(np.ptp(uv, axis=0).max() / 128)
    ratio = np.array(spans["garment"]) / np.array(spans["body"])
    assert np.all(ratio > 1.4)  # the same cameras, zoomed (1.5-1.7x for this box; 1.85x for the t-shirt)
    assert min(spans["garment"]) > 0.6


def test_unknown_framing_is_a_clear_error():
    from pgc.errors import PGCDataError
    from pgc.synth.generate import framing_sphere

    with pytest.raises(PGCDataError, match="framing 'face'.*'body' or 'garment'"):
        framing_sphere("face", 1.7, np.zeros((3, 3)))


def test_relighting_envmaps():
    for kind in ("sky", "studio"):
        env = rig.relight_envmap(16, kind)
        assert env.shape == (16, 32, 3) and np.all(np.isfinite(env)) and env.min() >= 0
    with pytest.raises(Exception, match="unknown environment map"):
        rig.relight_envmap(16, "moon")
