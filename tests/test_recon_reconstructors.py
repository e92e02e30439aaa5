"""The four reconstructors end to end on a small synthetic capture, and their bad-input errors."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCConfigError, PGCDataError
from pgc.geometry import metrics
from pgc.geometry.hull import pixel_footprint
from pgc.testing.capture_scenes import body_mesh, make_capture
from pgc.io.mesh import write_mesh
from pgc.registry import Registry
from pgc.types import Mesh

pytest.importorskip("pymeshlab", reason="finishing needs pymeshlab: pip install 'pgc[meshlab]'")

SMALL = dict(target_vertices=1500)


@pytest.fixture(scope="module")
def registry():
    return Registry.discover()


@pytest.fixture(scope="module")
def scene():
    cap, gt = make_capture(body_mesh(0.02), views=12, size=96)
    return cap, gt, pixel_footprint(cap.cameras, gt.vertices.mean(0))


def _check(rec, gt, fp, chamfer_px: float, iou: float):
    mesh, fig = rec.mesh, rec.figures
    assert metrics.is_manifold(fig) and fig["degenerate_faces"] == 0
    assert mesh.uv is not None and mesh.face_labels is not None
    m = metrics.compare_meshes(mesh, gt, samples=20_000)
    assert m["chamfer_mean"] < chamfer_px * fp, m
    assert metrics.label_iou(mesh, gt, [2]) > iou
    return m


def test_every_reconstructor_is_registered(registry):
    names = {i.name: i for i in registry.list("reconstructor")}
    assert {"open3d", "colmap", "mesh", "visual_hull"} <= set(names)
    assert all(names[n].available for n in ("open3d", "colmap", "mesh", "visual_hull"))


def test_options_are_validated(registry):
    with pytest.raises(PGCConfigError, match="target_vertices"):
        registry.get("reconstructor", "visual_hull").validate_options({"target_vertices": 10})
    with pytest.raises(PGCConfigError, match="transform"):
        registry.get("reconstructor", "mesh").validate_options({"path": "x.obj", "transform": [1, 2, 3]})


def test_visual_hull_reconstructor(registry, scene):
    cap, gt, fp = scene
    rec = registry.create("reconstructor", "visual_hull", SMALL).reconstruct(cap)
    _check(rec, gt, fp, chamfer_px=0.5, iou=0.85)
    assert rec.figures["seconds_hull"] > 0


def test_mesh_reconstructor_takes_a_users_scan(registry, scene, tmp_path):
    cap, _, fp = scene
    gt = body_mesh(0.04)  # a coarser scan of the same body
    # the scan in millimetres and shifted: the transform brings it to the capture frame
    shift = np.array([0.1, -0.05, 0.2])
    write_mesh(tmp_path / "scan.ply", Mesh(gt.vertices * 1000.0 + shift * 1000.0, gt.faces))
    T = np.eye(4)
    T[:3, :3] *= 0.001
    T[:3, 3] = -shift
    rec = registry.create("reconstructor", "mesh", dict(SMALL, path=str(tmp_path / "scan.ply"),
                                                        transform=T.ravel().tolist(), remesh=False)).reconstruct(cap)
    assert len(rec.mesh.faces) >= 0.995 * len(gt.faces)  # topology kept (up to repairs of slivers)
    assert metrics.compare_meshes(rec.mesh, gt, samples=20_000)["chamfer_mean"] < 1e-6 + 0.02 * fp
    assert metrics.label_iou(rec.mesh, gt, [2]) > 0.95
    assert rec.figures["silhouette_iou"] > 0.9


def test_mesh_reconstructor_refines_a_small_misalignment(registry, scene, tmp_path):
    cap, _, fp = scene
    gt = body_mesh(0.04)
    write_mesh(tmp_path / "scan.obj", Mesh(gt.vertices + [0.03, 0.0, -0.02], gt.faces))
    rec = registry.create("reconstructor", "mesh", dict(SMALL, path=str(tmp_path / "scan.obj"),
                                                        refine_alignment=True)).reconstruct(cap)
    assert metrics.compare_meshes(rec.mesh, gt, samples=20_000)["chamfer_mean"] < 0.5 * fp


def test_mesh_reconstructor_bad_inputs(registry, scene, tmp_path):
    cap, gt, _ = scene
    far = tmp_path / "far.ply"
    write_mesh(far, Mesh(gt.vertices + [2.0, 0.0, 0.0], gt.faces))
    with pytest.raises(PGCDataError, match="not in the capture's frame"):
        registry.create("reconstructor", "mesh", dict(SMALL, path=str(far))).reconstruct(cap)
    junk = tmp_path / "junk.obj"
    junk.write_text("this is not a mesh\n")
    with pytest.raises(PGCDataError, match="junk.obj"):
        registry.create("reconstructor", "mesh", dict(SMALL, path=str(junk))).reconstruct(cap)
    points = tmp_path / "points.ply"
    points.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
    with pytest.raises(PGCDataError, match="points.ply"):
        registry.create("reconstructor", "mesh", dict(SMALL, path=str(points))).reconstruct(cap)


def test_too_few_views_fail_before_work(registry, scene):
    cap, _, _ = scene
    from pgc.types import Capture

    few = Capture(cap.views[:3], labels=cap.labels)
    for name in ("visual_hull", "open3d", "colmap"):
        with pytest.raises(PGCDataError, match="at least"):
            registry.create("reconstructor", name, SMALL).reconstruct(few)


@pytest.mark.slow
def test_open3d_reconstructor(registry, scene):
    cap, gt, fp = scene
    rec = registry.create("reconstructor", "open3d", SMALL).reconstruct(cap)
    _check(rec, gt, fp, chamfer_px=0.4, iou=0.9)
    assert rec.figures["stereo_points"] > 300 and rec.figures["poisson_depth"] >= 6


@pytest.fixture(scope="module")
def textured_scene():
    # SIFT needs more pixels and closer views than the other tests: 32 views at 160 px
    cap, gt = make_capture(body_mesh(0.02), views=32, size=160)
    return cap, gt, pixel_footprint(cap.cameras, gt.vertices.mean(0))


@pytest.mark.slow
def test_colmap_reconstructor(registry, textured_scene):
    cap, gt, fp = textured_scene
    rec = registry.create("reconstructor", "colmap", SMALL).reconstruct(cap)
    _check(rec, gt, fp, chamfer_px=0.5, iou=0.9)
    assert rec.figures["sparse_points"] > 20
    assert rec.figures["sparse_reprojection_px"] < 1.0  # the known cameras explain the SIFT matches


def test_umeyama_recovers_a_similarity():
    from scipy.spatial.transform import Rotation

    from pgc_colmap.calibrate import umeyama

    rng = np.random.default_rng(0)
    src = rng.normal(size=(10, 3))
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    s, R2, t = umeyama(src, 2.5 * src @ R.T + [1.0, 2.0, 3.0])
    assert s == pytest.approx(2.5)
    np.testing.assert_allclose(R2, R, atol=1e-12)
    np.testing.assert_allclose(t, [1.0, 2.0, 3.0], atol=1e-12)


def test_colmap_dense_array_round_trip(tmp_path):
    from pgc_colmap.workspace import read_dense_array, write_dense_array

    a = np.random.default_rng(0).random((5, 7, 3)).astype(np.float32)
    write_dense_array(tmp_path / "n.bin", a)
    np.testing.assert_array_equal(read_dense_array(tmp_path / "n.bin"), a)
    d = a[..., 0]
    write_dense_array(tmp_path / "d.bin", d)
    raw = (tmp_path / "d.bin").read_bytes()
    assert raw.startswith(b"7&5&1&")
    # one plane per channel, each stored row by row (x fastest): the second value is row 0, column 1
    assert np.frombuffer(raw[6:14], np.float32)[1] == d[0, 1]
    np.testing.assert_array_equal(read_dense_array(tmp_path / "d.bin"), d)


def test_stereo_runs_on_an_even_spread_of_the_views(registry, scene):
    from scipy.spatial import cKDTree

    from pgc.geometry.dense import dense_points
    from pgc.geometry.options import DenseOptions

    cap, gt = make_capture(body_mesh(0.02), views=24, size=96)
    fp = pixel_footprint(cap.cameras, gt.vertices.mean(0))
    dense = dense_points(cap, DenseOptions(stereo_views=12))
    assert dense.stereo_ids == [0, 2, 4, 6, 8, 10, 13, 15, 17, 19, 21, 23] and len(dense.depths) == 12
    stereo = dense.points[:dense.stereo_points]
    dist = cKDTree(metrics.sample_surface(gt, 50_000, seed=0)[0]).query(stereo)[0]
    assert dense.stereo_points > 300 and np.median(dist) < 0.5 * fp
    assert dense_points(scene[0], DenseOptions(stereo_views=64)).stereo_ids == list(range(12))  # fewer: every view
    with pytest.raises(PGCConfigError, match="stereo_views"):
        registry.get("reconstructor", "open3d").validate_options({"stereo_views": 1})


def test_spread_keeps_the_ends_and_spaces_evenly():
    from pgc.sampling import spread

    assert spread(list(range(12)), 6) == [0, 2, 4, 7, 9, 11]
    assert spread(list("abc"), 5) == ["a", "b", "c"] and spread(list(range(9)), 2) == [0, 8]
