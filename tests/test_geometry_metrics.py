"""Mesh metrics on analytic cases: concentric spheres, cubes, broken topology, UV overlaps."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.geometry import metrics
from pgc.geometry.surface_nets import surface_nets
from pgc.types import Mesh


def _sphere(radius: float, spacing: float = 0.03) -> Mesh:
    ax = np.arange(-1.0, 1.0 + 1e-9, spacing)
    p = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1)
    v, f = surface_nets(np.linalg.norm(p, axis=-1) - radius, np.full(3, -1.0), spacing)
    v = v / np.linalg.norm(v, axis=1, keepdims=True) * radius  # exactly on the sphere
    return Mesh(v, f)


def _cube() -> Mesh:
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return Mesh(v, f)


def test_concentric_spheres_chamfer_and_fscore():
    a, b = _sphere(0.5), _sphere(0.52)
    m = metrics.compare_meshes(a, b, samples=40_000, thresholds=(0.01, 0.04))
    assert m["chamfer_mean"] == pytest.approx(0.02, rel=0.08)
    assert m["normal_consistency"] > 0.99
    assert m["fscore_10mm"] < 0.05 and m["fscore_40mm"] > 0.99


def test_label_iou_identity_and_complement():
    s = _sphere(0.5)
    s.face_labels = np.where(s.vertices[s.faces].mean(1)[:, 1] > 0, 2, 1)
    assert metrics.label_iou(s, s, [2]) > 0.99
    flipped = Mesh(s.vertices, s.faces, face_labels=3 - s.face_labels)
    assert metrics.label_iou(flipped, s, [2]) < 0.01


def test_topology_of_a_cube():
    r = metrics.topology_report(_cube())
    assert metrics.is_manifold(r)
    assert r["boundary_edges"] == 0 and r["components"] == 1
    assert r["min_angle_deg"] == pytest.approx(45.0)


def test_broken_topology_is_detected():
    c = _cube()
    f = c.faces.copy()
    f[0] = f[0][::-1]
    assert metrics.topology_report(Mesh(c.vertices, f))["misoriented_edges"] == 3
    # two tetra-like fans sharing only a vertex: a bow-tie
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    bow = metrics.topology_report(Mesh(v, [[0, 1, 2], [0, 3, 4]]))
    assert bow["non_manifold_vertices"] == 1 and bow["components"] == 2
    # three faces on one edge
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    assert metrics.topology_report(Mesh(v, [[0, 1, 2], [1, 0, 3], [0, 1, 4]]))["non_manifold_edges"] == 1
    # a zero-area face is degenerate, its angles finite
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    r = metrics.topology_report(Mesh(v, [[0, 1, 2]]))
    assert r["degenerate_faces"] == 1 and np.isfinite(r["min_angle_deg"])


def test_uv_overlap():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    uv = np.array([[0.1, 0.1], [0.5, 0.1], [0.1, 0.5], [0.5, 0.5], [0.2, 0.2], [0.2, 0.6]], np.float32)
    disjoint = Mesh(v, f, uv, np.array([[0, 1, 2], [1, 3, 2]]))
    assert metrics.uv_overlap(disjoint, 256)["overlap_fraction"] == 0.0
    overlapping = Mesh(v, f, uv, np.array([[0, 1, 2], [4, 3, 5]]))
    assert metrics.uv_overlap(overlapping, 256)["overlap_fraction"] > 0.01


def test_closest_point_on_triangles_matches_dense_sampling():
    rng = np.random.default_rng(3)
    n = 100
    a, b, c = rng.normal(size=(3, n, 3))
    p = rng.normal(size=(n, 3)) * 2
    q = metrics.closest_point_on_triangles(p, a, b, c)
    u, v = np.meshgrid(np.linspace(0, 1, 151), np.linspace(0, 1, 151))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    dense = a[:, None] + u[None, :, None] * (b - a)[:, None] + v[None, :, None] * (c - a)[:, None]
    brute = np.linalg.norm(dense - p[:, None], axis=2).min(1)
    d = np.linalg.norm(q - p, axis=1)
    assert np.all(d <= brute + 1e-12) and np.all(brute - d < 0.02)
    # degenerate triangles (a point, a segment) stay finite
    z = np.zeros((1, 3))
    e = np.array([[1.0, 0, 0]])
    assert np.isfinite(metrics.closest_point_on_triangles(np.ones((1, 3)), z, z, z)).all()
    np.testing.assert_allclose(metrics.closest_point_on_triangles(np.array([[0.5, 1, 0]]), z, e, 2 * e), [[0.5, 0, 0]])


def test_chamfer_of_a_mesh_with_itself_is_zero():
    s = _sphere(0.5)
    assert metrics.compare_meshes(s, s, samples=5000)["chamfer_mean"] < 1e-9


def test_visible_faces_counts_cameras():
    from pgc.testing.capture_scenes import look_at

    # two quads at z = 2: the left one in front of both cameras, the right one only in front of camera b
    v = np.array([[-0.5, -0.5, 2], [0.5, -0.5, 2], [0.5, 0.5, 2], [-0.5, 0.5, 2],
                  [9.5, -0.5, 2], [10.5, -0.5, 2], [10.5, 0.5, 2], [9.5, 0.5, 2]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    a = look_at([0, 0, 0], [0, 0, 1], 32, 32, 60.0, "a")
    b = look_at([5, 0, -8], [5, 0, 2], 32, 32, 80.0, "b")
    m = Mesh(v, f)
    np.testing.assert_array_equal(metrics.visible_faces(m, [a, b]), [True, True, True, True])
    np.testing.assert_array_equal(metrics.visible_faces(m, [a, b], min_views=2), [True, True, False, False])
