"""The torch splat fit on a small scene made here (the test body of pgc.testing.capture_scenes): it learns,
keeps only the garment's Gaussians, chooses SH degree and count from held-out views, resumes from a checkpoint."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.testing.capture_scenes import body_mesh, make_capture
from pgc.roles.splat_renderer import FitSplatsSettings

torch = pytest.importorskip("torch")

from pgc.splats.fitplan import crop_view, focus_on_garment, initial_count  # noqa: E402
from pgc.splats.init import colors_from_views, sample_on_mesh  # noqa: E402
from pgc.splats.fit import views_psnr  # noqa: E402
from pgc_torch.splat.renderer import TorchSplatRenderer  # noqa: E402

FAST = {"iterations": 40, "gaussians_per_pixel": 0.5, "holdout_every": 4, "log_every": 10}


@pytest.fixture(scope="module")
def scene():
    capture, mesh = make_capture(body_mesh(0.04), views=8, size=40)
    return capture, mesh


class Recorder:
    def __init__(self, stop_at: int | None = None) -> None:
        self.progress: list[tuple[int, dict]] = []
        self.finished: dict = {}
        self.stop_at = stop_at

    def pgc_stage_started(self, stage, info):
        pass

    def pgc_stage_progress(self, stage, done, total, figures):
        self.progress.append((done, figures))
        if self.stop_at is not None and done >= self.stop_at:
            raise KeyboardInterrupt  # a crash in the middle of the fit

    def pgc_stage_finished(self, stage, seconds, figures):
        self.finished = figures


@pytest.mark.slow
def test_fit_learns_keeps_garment_and_selects_on_heldout_views(scene):
    capture, mesh = scene
    renderer = TorchSplatRenderer({"threads": 2})
    rec = Recorder()
    fit = renderer.fit(capture, mesh, FAST, Reporter(rec))
    g, f = fit.gaussians, fit.figures
    focused, _ = focus_on_garment(capture, mesh, FitSplatsSettings(**FAST))
    assert f["iterations"] == 40 and f["initial_gaussians"] == initial_count(focused, FitSplatsSettings(**FAST))
    losses = [fig["loss"] for _, fig in rec.progress if "loss" in fig]
    assert losses[-1] < 0.7 * losses[0]
    assert f["psnr_heldout"] >= f["psnr_heldout_full"] - FitSplatsSettings().margin_db - 1e-9
    assert f["psnr_heldout"] > 20.0
    assert np.all(mesh.face_labels[g.parent] == 2) and len(g) == f["gaussians"] > 0
    assert g.sh_degree == f["sh_degree"] and set(f["sh_selection"]) == {str(d) for d in range(4)}
    assert [p["iteration"] for p in f["time_to_psnr"]][-1] == 40
    assert all(np.all(np.isfinite(getattr(g, n))) for n in ("means", "quats", "log_scales", "opacity_logits", "sh"))


@pytest.mark.slow
def test_fit_resumes_from_checkpoint_after_a_crash(scene, tmp_path):
    capture, mesh = scene
    settings = dict(FAST, iterations=20, checkpoint_every=10, log_every=5, keep="all", select_count=False,
                    select_sh=False, prune_weight=0.0, checkpoint_dir=str(tmp_path))
    renderer = TorchSplatRenderer({"threads": 1})
    straight = renderer.fit(capture, mesh, dict(settings, checkpoint_dir=None)).gaussians
    with pytest.raises(KeyboardInterrupt):
        renderer.fit(capture, mesh, settings, Reporter(Recorder(stop_at=15)))
    assert (tmp_path / "fit_splats_torch.npz").exists()
    rec = Recorder()
    resumed = renderer.fit(capture, mesh, settings, Reporter(rec)).gaussians
    assert rec.progress[0][0] > 10  # started after the checkpoint of step 10, not from 0
    for name in ("means", "quats", "log_scales", "opacity_logits", "sh"):
        np.testing.assert_allclose(getattr(resumed, name), getattr(straight, name), atol=2e-4)


def test_unlabelled_mesh_is_a_clear_error(scene):
    capture, mesh = scene
    unlabelled = type(mesh)(mesh.vertices, mesh.faces, name="scan")
    with pytest.raises(PGCDataError, match="keep = 'all'"):
        TorchSplatRenderer().fit(capture, unlabelled, FAST)


def test_heldout_psnr_of_the_ground_truth_layout_is_high(scene):
    """Sanity of the evaluation path: Gaussians that exactly reproduce an image give a high PSNR on it."""
    from dataclasses import replace

    from pgc.splats.fit import FitView, _Prepared
    from pgc_torch.splat.fit import TorchFitBackend

    capture, mesh = scene
    backend = TorchFitBackend(TorchSplatRenderer())
    g = sample_on_mesh(mesh, 500, np.random.default_rng(0), 0)
    g.opacity_logits[:] = -30.0  # invisible: the render is the background
    backend.start(g, mesh)
    views = []
    for v in capture.views:
        fv = FitView.of(v, 0.03)
        fv = replace(fv, image=fv.background.copy())
        views.append(_Prepared(fv, backend.prepare(fv)))
    assert views_psnr(backend, views, 0) > 60


def test_backfacing_faces_are_those_no_camera_sees_from_the_front():
    from pgc.types import Camera, Mesh
    from pgc.splats.fitplan import backfacing_faces as _backfacing_faces

    mesh = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 1]]))  # normals +z, -z
    front = Camera(np.eye(3), np.diag([1.0, -1.0, -1.0]), [0, 0, 5.0], 4, 4)  # at z = +5 looking down -z
    np.testing.assert_array_equal(_backfacing_faces(mesh, [front]), [False, True])


def test_a_cropped_view_renders_the_crop_of_the_full_render(scene):
    from pgc.splats.binding import bind

    capture, mesh = scene
    g = sample_on_mesh(mesh, 400, np.random.default_rng(2), 1)
    g.opacity_logits[:] = 1.0
    view = capture.views[1]
    crop = crop_view(view, 7, 5, 31, 36)
    renderer = TorchSplatRenderer({"threads": 1})
    world = bind(g, mesh.vertices, mesh.faces)
    full, part = renderer.render(world, view.camera), renderer.render(world, crop.camera)
    assert part.color.shape == (31, 24, 3) and crop.image.shape == (31, 24, 3)
    np.testing.assert_array_equal(crop.image, view.image[5:36, 7:31])
    np.testing.assert_allclose(part.color, full.color[5:36, 7:31], atol=1e-5)
    np.testing.assert_allclose(part.alpha, full.alpha[5:36, 7:31], atol=1e-5)


def test_focus_crops_keep_every_garment_pixel_and_the_garment_faces(scene):
    capture, mesh = scene
    s = FitSplatsSettings(**FAST)
    focused, faces = focus_on_garment(capture, mesh, s)
    ids = list(capture.garment_label_ids)
    assert len(focused.views) == sum(bool(np.isin(v.segmentation, ids).any()) for v in capture.views)
    for full, crop in zip([v for v in capture.views if np.isin(v.segmentation, ids).any()], focused.views):
        assert np.isin(crop.segmentation, ids).sum() == np.isin(full.segmentation, ids).sum()
        assert crop.image.size < full.image.size
    garment = np.isin(mesh.face_labels, ids)
    assert faces[garment].all() and 0 < faces.sum() < len(faces)
    same, none = focus_on_garment(capture, mesh, s.model_copy(update={"focus": "all"}))
    assert same is capture and none is None


def test_initial_colours_are_the_colour_of_the_images_that_see_them(scene):
    capture, mesh = scene
    colour = np.array([0.2, 0.45, 0.7], np.float32)
    views = [type(v)(v.camera, np.broadcast_to(colour, v.image.shape).copy()) for v in capture.views]
    g = sample_on_mesh(mesh, 300, np.random.default_rng(3), 0)
    coloured = colors_from_views(g, mesh, views)
    from pgc.splats.sh import sh_to_rgb_dc

    rgb = sh_to_rgb_dc(coloured.sh[:, 0])
    changed = np.any(coloured.sh != g.sh, axis=(1, 2))
    assert changed.mean() > 0.8  # all but Gaussians no camera sees
    np.testing.assert_allclose(rgb[changed], np.broadcast_to(colour, rgb[changed].shape), atol=1e-6)
    np.testing.assert_array_equal(coloured.sh[~changed], g.sh[~changed])
