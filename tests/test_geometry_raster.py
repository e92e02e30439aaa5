"""The numpy rasteriser and surface nets against analytic answers."""

from __future__ import annotations

import numpy as np

from pgc.geometry.raster import rasterize
from pgc.geometry.surface_nets import surface_nets
from pgc.testing.capture_scenes import look_at
from pgc.types import Mesh


def _square(z: float, half: float = 5.0, tilt: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[-half, -half, z - tilt * half], [half, -half, z + tilt * half],
                  [half, half, z + tilt * half], [-half, half, z - tilt * half]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _camera(size: int = 32):
    return look_at([0, 0, 0], [0, 0, 1], size, size, 60.0, "c")


def test_fronto_parallel_plane_depth_is_exact():
    cam = _camera()
    v, f = _square(2.0)
    r = rasterize(cam, v, f)
    assert (r.face_id >= 0).all()
    np.testing.assert_allclose(r.depth, 2.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.bary.sum(-1), 1.0, atol=1e-12)


def test_tilted_plane_matches_ray_intersection():
    cam = _camera()
    v, f = _square(3.0, tilt=0.3)  # plane z = 3 + 0.3 x
    r = rasterize(cam, v, f)
    origin, dirs = cam.rays()
    # z of the ray hitting z = 3 + 0.3 x: t d_z = 3 + 0.3 t d_x
    t = 3.0 / (dirs[..., 2] - 0.3 * dirs[..., 0])
    np.testing.assert_allclose(r.depth, t * dirs[..., 2], rtol=1e-10)
    # perspective-correct barycentrics reproduce the 3D hit point
    hit = np.einsum("hwk,hwkj->hwj", r.bary, v[f[r.face_id]])
    np.testing.assert_allclose(hit, origin + t[..., None] * dirs, atol=1e-9)


def test_nearer_surface_occludes_and_degenerates_cover_nothing():
    cam = _camera()
    far_v, far_f = _square(4.0)
    near_v, near_f = _square(2.0, half=0.2)
    degenerate = np.array([[0, 0, 1.0], [0, 0, 1.0], [0.1, 0, 1.0], [0.2, 0, 1.0], [0.4, 0, 1.0]])
    behind = np.array([[-1, -1, -1.0], [1, -1, -1.0], [0, 1, -1.0]])
    v = np.concatenate([far_v, near_v, degenerate, behind])
    f = np.concatenate([far_f, near_f + 4, [[8, 9, 10], [10, 11, 12]], [[13, 14, 15]]])
    r = rasterize(cam, v, f)
    assert set(np.unique(r.face_id)) == {0, 1, 2, 3}
    assert np.isfinite(r.depth).all()
    np.testing.assert_allclose(r.depth[r.face_id >= 2], 2.0, atol=1e-12)
    np.testing.assert_allclose(r.depth[r.face_id < 2], 4.0, atol=1e-12)


def test_surface_nets_sphere_is_closed_outward_and_accurate():
    spacing, radius = 0.05, 0.6
    ax = np.arange(-1.0, 1.0 + 1e-9, spacing)
    p = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1)
    v, f = surface_nets(np.linalg.norm(p, axis=-1) - radius, np.array([-1.0, -1.0, -1.0]), spacing)
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - radius).max() < 0.25 * spacing
    m = Mesh(v, f)
    t = v[f]
    volume = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6
    assert abs(volume / (4 / 3 * np.pi * radius ** 3) - 1) < 0.03
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    assert (np.unique(e, axis=0, return_counts=True)[1] == 2).all()  # closed, edge-manifold
    assert (np.einsum("ij,ij->i", m.face_normals(), t.mean(1)) > 0).all()  # outward


def test_surface_nets_without_sign_change_is_empty():
    v, f = surface_nets(np.ones((4, 4, 4)), np.zeros(3), 1.0)
    assert len(v) == 0 and len(f) == 0
