"""Visual hull, plane-sweep stereo and label voting on a small synthetic capture with known geometry."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.geometry import metrics
from pgc.geometry.hull import _axis_centre, check_views, pixel_footprint, visual_hull
from pgc.geometry.labels import vote_face_labels
from pgc.geometry.raster import rasterize
from pgc.geometry.stereo import StereoSettings, consistency_filter, sweep_depth
from pgc.geometry.surface_nets import surface_nets
from pgc.testing.capture_scenes import look_at, make_capture, render_view
from pgc.types import BODY_LABEL, GARMENT_LABEL, Mesh, View


@pytest.fixture(scope="module")
def scene():
    return make_capture(views=12, size=96)


def test_visual_hull_contains_and_approximates_the_object(scene):
    cap, gt = scene
    v, f, field = visual_hull(cap.views)
    fp = pixel_footprint(cap.cameras, v.mean(0))
    # The hull contains the object: ground-truth vertices lie inside (up to the mask's pixel quantisation).
    assert np.mean(field(gt.vertices) <= 0.5 * fp) > 0.99
    m = metrics.compare_meshes(Mesh(v, f), gt, samples=20_000)
    assert m["completeness_mean"] < 0.6 * fp


def test_bad_captures_fail_clearly(scene):
    cap, _ = scene
    with pytest.raises(PGCDataError, match="at least 4"):
        check_views(cap.views[:3], 4)
    empty = [replace(cap.views[0], mask=np.zeros_like(cap.views[0].mask))] + cap.views[1:]
    with pytest.raises(PGCDataError, match="empty foreground mask.*cam000"):
        check_views(empty, 4)
    # one camera turned to look away (a pose in the wrong convention): the silhouettes cannot intersect
    c = cap.views[0].camera
    away = replace(c, R=np.diag([-1.0, 1.0, -1.0]) @ c.R, t=np.diag([-1.0, 1.0, -1.0]) @ c.t)
    views = [View(away, cap.views[0].image, cap.views[0].mask)] + cap.views[1:]
    with pytest.raises(PGCDataError, match="do not see a common object"):
        visual_hull(views)


def test_plane_sweep_depth_is_subpixel_and_consistency_removes_outliers(scene):
    cap, _ = scene
    v, f, _ = visual_hull(cap.views)
    masks = check_views(cap.views, 4)
    hull_depths = [rasterize(view.camera, v, f).depth for view in cap.views]
    centre = _axis_centre(cap.cameras)
    settings = StereoSettings()
    fp = pixel_footprint(cap.cameras, v.mean(0))
    depths = [sweep_depth(cap.views, i, hull_depths[i], masks, settings, centre)[0] for i in range(len(cap.views))]
    d, gt = depths[0], cap.views[0].extras["depth"]
    ok = d > 0
    assert ok.sum() > 0.4 * masks[0].sum()
    assert np.median(np.abs(d[ok] - gt[ok])) < 0.5 * fp
    corrupted = [x.copy() for x in depths]
    corrupted[0][ok] *= 1.05  # 5 % too far: no neighbour agrees
    kept = consistency_filter(cap.cameras, corrupted, settings, centre)
    assert (kept[0] > 0).sum() < 0.05 * ok.sum()
    kept = consistency_filter(cap.cameras, depths, settings, centre)[0]
    assert (kept > 0).sum() > 0.4 * ok.sum()
    good = kept > 0
    assert np.percentile(np.abs(kept[good] - gt[good]), 90) <= np.percentile(np.abs(d[ok] - gt[ok]), 90)


def test_label_vote_recovers_ground_truth_labels(scene):
    cap, gt = scene
    labels, conf = vote_face_labels(gt.vertices, gt.faces, cap.views, 3)
    seen = conf > 0
    assert seen.mean() > 0.8
    area = gt.face_areas()
    assert np.sum(area * (labels == gt.face_labels)) / area.sum() > 0.98
    assert set(np.unique(labels)) <= {1, 2}  # background never wins


def test_label_vote_ignores_views_without_segmentation(scene):
    cap, gt = scene
    views = [View(v.camera, v.image, v.mask) for v in cap.views]
    labels, conf = vote_face_labels(gt.vertices, gt.faces, views, 3)
    assert (conf == 0).all() and np.isfinite(labels).all()


def skirt_hull(legs: bool, spacing: float = 0.02) -> Mesh:
    """What a visual hull makes of a skirt (radius 0.3 m, hem at y = 0.6 m): a closed drum whose floor spans the
    hem, with (``legs``) two legs (body) coming out of the floor; everything above y = 0.59 m is garment."""
    lo, hi = np.array([-0.45, -0.05, -0.45]), np.array([0.45, 1.35, 0.45])
    n = np.ceil((hi - lo) / spacing).astype(int) + 1
    p = np.stack(np.meshgrid(*[lo[i] + spacing * np.arange(n[i]) for i in range(3)], indexing="ij"), -1).reshape(-1, 3)
    field = np.maximum(np.hypot(p[:, 0], p[:, 2]) - 0.3, np.maximum(0.6 - p[:, 1], p[:, 1] - 1.2))
    for x in (-0.12, 0.12) if legs else ():
        field = np.minimum(field, np.maximum(np.hypot(p[:, 0] - x, p[:, 2]) - 0.07, np.maximum(-p[:, 1], p[:, 1] - 0.7)))
    v, f = surface_nets(field.reshape(n), lo, spacing)
    return Mesh(v, f, face_labels=np.where(v[f].mean(1)[:, 1] > 0.59, GARMENT_LABEL, BODY_LABEL).astype(np.int32))


@pytest.mark.parametrize("legs", [True, False], ids=["legs", "no-legs"])
def test_label_vote_leaves_the_unseen_floor_under_a_skirt_to_the_body_it_borders(legs):
    """Cameras above the hem never see the floor the hull spans across the skirt's opening. Beside the legs it is
    body (no cloth spans a skirt's opening); with no body beside it, it is a patch of the garment no camera saw."""
    mesh = skirt_hull(legs)
    cameras = [look_at(np.array([2.5 * np.cos(e) * np.sin(a), 0.8 + 2.5 * np.sin(e), 2.5 * np.cos(e) * np.cos(a)]),
                       np.array([0.0, 0.6, 0.0]), 64, 64, 45.0, f"c{i}")
               for i, (e, a) in enumerate((e, a) for e in np.radians([5, 35]) for a in np.radians(np.arange(0, 360, 45)))]
    views = [render_view(mesh, c) for c in cameras]
    labels, conf = vote_face_labels(mesh.vertices, mesh.faces, views, 3)
    centre, area = mesh.vertices[mesh.faces].mean(1), mesh.face_areas()
    floor = (centre[:, 1] < 0.61) & (mesh.face_normals()[:, 1] < -0.99)  # its flat part; the rim's faces are seen
    wall = (centre[:, 1] > 0.65) & (mesh.face_labels == GARMENT_LABEL)
    assert floor.sum() > 900 and (conf[floor] == 0).all()
    garment_share = lambda part: np.sum(area[part] * (labels[part] == GARMENT_LABEL)) / area[part].sum()  # noqa: E731
    assert garment_share(wall) == 1.0
    assert garment_share(floor) == (0.0 if legs else 1.0)


def test_poisson_depth_of_no_points_is_a_clear_error():
    from pgc.geometry.dense import poisson_depth_for

    with pytest.raises(PGCDataError, match="no points to mesh"):
        poisson_depth_for(np.zeros((0, 3)), 0.01)
