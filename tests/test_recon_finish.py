"""Shared finishing steps: cleaning, orientation, remeshing to a target, UV atlas, garment sub-mesh."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.geometry import finish as finish_mod
from pgc.geometry import metrics
from pgc.geometry.garment import garment_selection
from pgc.geometry.hull import visual_hull
from pgc.geometry.options import FinishOptions
from pgc.testing.capture_scenes import body_mesh, make_capture
from pgc.types import Mesh

for _module in ("pymeshlab", "xatlas"):
    pytest.importorskip(_module, reason="needs pymeshlab + xatlas: pip install 'pgc[meshlab]'")


@pytest.fixture(scope="module")
def scene():
    return make_capture(body_mesh(0.02), views=12, size=96)


@pytest.fixture(scope="module")
def finished(scene):
    cap, _ = scene
    v, f, _ = visual_hull(cap.views)
    return finish_mod.finish(v, f, cap.views, cap.labels, FinishOptions(target_vertices=2500))


def test_finished_mesh_is_simulation_quality(finished, scene):
    mesh, fig = finished
    assert metrics.is_manifold(fig) and fig["boundary_edges"] == 0 and fig["components"] == 1
    assert fig["degenerate_faces"] == 0 and fig["min_angle_deg"] > 8.0
    assert abs(len(mesh.vertices) / 2500 - 1) < 0.15
    assert metrics.uv_overlap(mesh, 512)["overlap_fraction"] < 1e-4
    uv_area = metrics.uv_overlap(mesh, 512)["texels_covered"] / 512 ** 2
    assert uv_area > 0.3  # the atlas is packed, not a speck
    assert metrics.label_iou(mesh, scene[1], [2]) > 0.85
    assert np.all(np.isfinite(mesh.vertices))


def test_orient_repairs_random_flips_and_inside_out():
    m = body_mesh(0.04)
    rng = np.random.default_rng(1)
    f = m.faces.copy()
    flip = rng.random(len(f)) < 0.4
    f[flip] = f[flip][:, ::-1]
    np.testing.assert_array_equal(finish_mod.orient(m.vertices, f), m.faces)
    np.testing.assert_array_equal(finish_mod.orient(m.vertices, m.faces[:, ::-1]), m.faces)


def test_clean_drops_specks_and_closes_holes():
    m = body_mesh(0.04)
    speck_v = np.array([[3, 3, 3], [3.01, 3, 3], [3, 3.01, 3], [3, 3, 3.01]], float)
    speck_f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]) + len(m.vertices)
    keep = np.ones(len(m.faces), bool)
    keep[[10, 11, 12]] = False  # a small hole
    v = np.concatenate([m.vertices, speck_v])
    f = np.concatenate([m.faces[keep], speck_f])
    v2, f2 = finish_mod.clean(v, f)
    r = metrics.topology_report(Mesh(v2, f2))
    assert r["components"] == 1 and r["boundary_edges"] == 0 and metrics.is_manifold(r)


def test_clean_rejects_empty_input():
    with pytest.raises(PGCDataError, match="empty mesh"):
        finish_mod.clean(np.zeros((0, 3)), np.zeros((0, 3), np.int64))


def test_garment_submesh_is_one_clean_manifold_patch(finished):
    mesh, _ = finished
    garment, sel = finish_mod.extract_garment(mesh, [2], min_island_faces=20, resolution=512)
    r = metrics.topology_report(garment)
    assert r["components"] == 1 and metrics.is_manifold(r) and r["degenerate_faces"] == 0
    assert metrics.uv_overlap(garment, 512)["overlap_fraction"] < 1e-4
    # the boundary is made of closed loops: every boundary vertex has exactly two boundary edges
    e = np.sort(np.concatenate([garment.faces[:, [0, 1]], garment.faces[:, [1, 2]], garment.faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    boundary = uniq[counts == 1]
    assert len(boundary) > 0
    assert set(np.bincount(boundary.ravel())[np.unique(boundary)]) == {2}
    # the face selection maps garment faces to the full mesh in order
    np.testing.assert_allclose(garment.vertices[garment.faces], mesh.vertices[mesh.faces[sel]])


def test_garment_selection_without_garment_fails_clearly():
    m = body_mesh(0.05)
    m.face_labels[:] = 1
    with pytest.raises(PGCDataError, match="garment label"):
        garment_selection(m, [2])
    with pytest.raises(PGCDataError, match="no face labels"):
        garment_selection(Mesh(m.vertices, m.faces), [2])


def test_remove_slivers_keeps_a_closed_manifold():
    m = body_mesh(0.04)
    v = m.vertices.copy()
    edges = m.edges()[::97][:25]
    v[edges[:, 0]] = v[edges[:, 1]] + 0.02 * (v[edges[:, 0]] - v[edges[:, 1]])  # needles and caps
    m = Mesh(v, m.faces)
    assert metrics.topology_report(m)["min_angle_deg"] < 2.0
    v, f = finish_mod.remove_slivers(m.vertices, m.faces, min_angle_deg=10.0)
    r = metrics.topology_report(Mesh(v, f))
    assert metrics.is_manifold(r) and r["boundary_edges"] == 0 and r["components"] == 1
    assert r["min_angle_deg"] > 5.0 and r["degenerate_faces"] == 0
    # the surface stays where it was (collapses move vertices by half a short edge)
    assert metrics.compare_meshes(Mesh(v, f), m, samples=5000)["chamfer_mean"] < 0.005


def test_missing_meshlab_extra_is_one_clear_error(monkeypatch):
    import sys

    from pgc.errors import PGCPluginError

    monkeypatch.setitem(sys.modules, "xatlas", None)  # what an installation without the extra sees
    m = body_mesh(0.06)
    with pytest.raises(PGCPluginError, match=r"pip install 'pgc\[meshlab\]'"):
        finish_mod.unwrap(m.vertices, m.faces)


def test_remesh_decimates_a_much_finer_input_first_and_keeps_its_shape(monkeypatch):
    """Input over PREDECIMATE_ABOVE x the target is quadric-decimated to PREDECIMATE_TO x it before the
    isotropic passes; the result has the target count and lies on the input surface within 1 mm (a bumpy
    30 cm sphere of 164k vertices to 2000)."""
    trimesh = pytest.importorskip("trimesh")
    from pgc.sim.collision import signed_distance

    m = trimesh.creation.icosphere(subdivisions=7, radius=0.3)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    v = v + 0.02 * np.sin(6 * n[:, :1]) * np.cos(5 * n[:, 1:2]) * n
    seen = []
    original = finish_mod.decimate
    monkeypatch.setattr(finish_mod, "decimate", lambda *a: seen.append(a[2]) or original(*a))
    rv, rf = finish_mod.remesh(v, f, 2000)
    assert seen == [finish_mod.PREDECIMATE_TO * 2000]
    assert abs(len(rv) / 2000 - 1) <= 0.1
    assert np.abs(signed_distance(rv, v, f)).max() < 1e-3              # edges are ~2.3 cm
    assert np.abs(signed_distance(v[::50], rv, rf)).max() < 3e-3   # the other way: within a fraction of an edge
    seen.clear()
    small = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    finish_mod.remesh(np.asarray(small.vertices), np.asarray(small.faces), 2000)
    assert seen == []                                              # 2562 vertices: no decimation
