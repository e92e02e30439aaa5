"""The JAX splat fit: converges on a small scene made in the test, resumes from its checkpoint."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.events import Reporter
from pgc.metrics.psnr import psnr
from pgc.splats.binding import bind
from pgc.splats.init import sample_on_mesh
from pgc.types import Camera, Capture, GaussianSet, Mesh, View

pytest.importorskip("jax")
from pgc_jax.splat.renderer import JaxSplatRenderer  # noqa: E402

RES = 24


def _octahedron_sphere(radius: float = 0.3) -> Mesh:
    """A subdivided octahedron projected to a sphere (32 faces); faces below y = 0 are 'garment'."""
    v = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    f = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    verts, faces, cache = [np.array(p, float) for p in v], [], {}

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in cache:
            m = verts[a] + verts[b]
            verts.append(m / np.linalg.norm(m))
            cache[key] = len(verts) - 1
        return cache[key]

    for a, b, c in f:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    V, F = np.array(verts) * radius, np.array(faces)
    labels = np.where(V[F].mean(1)[:, 1] < 0, 2, 1).astype(np.int32)
    return Mesh(V, F, face_labels=labels, name="sphere")


def _camera(i: int, n: int) -> Camera:
    a = 2 * np.pi * i / n
    eye = np.array([np.sin(a), 0.3 * np.cos(3 * a), np.cos(a)]) * 1.2
    z = -eye / np.linalg.norm(eye)
    x = np.cross(z, [0.0, -1.0, 0.0])
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    f = RES * 1.1
    return Camera(K=[[f, 0, RES / 2], [0, f, RES / 2], [0, 0, 1]], R=R, t=-R @ eye, width=RES, height=RES, name=f"c{i}")


def _capture(renderer: JaxSplatRenderer, mesh: Mesh, n_views: int = 6) -> Capture:
    """Ground truth: random coloured Gaussians on the mesh, rendered over a grey background."""
    rng = np.random.default_rng(3)
    g = sample_on_mesh(mesh, 300, rng, 1)
    sh = np.concatenate([rng.normal(0, 0.8, (300, 1, 3)), rng.normal(0, 0.2, (300, 3, 3))], axis=1)
    gt = GaussianSet(g.parent, g.means, rng.normal(size=(300, 4)), np.log(rng.uniform(0.2, 0.6, (300, 3))),
                     np.full(300, 2.0), sh)
    world = bind(gt, mesh.vertices, mesh.faces)
    views = []
    for i in range(n_views):
        cam, bg = _camera(i, n_views), np.full((RES, RES, 3), 0.25, np.float32)
        out = renderer.render(world, cam, bg)
        views.append(View(cam, out.color, mask=(out.alpha > 0.5).astype(np.float32), background=bg))
    return Capture(views)


class _Progress:
    def __init__(self):
        self.events = []

    def pgc_stage_started(self, stage, info):
        pass

    def pgc_stage_progress(self, stage, done, total, figures):
        self.events.append(dict(figures, done=done))

    def pgc_stage_finished(self, stage, seconds, figures):
        pass


@pytest.mark.slow
@pytest.mark.parametrize("compositor", ["xla", "fused"])
def test_fit_converges_and_resumes(tmp_path, compositor):
    renderer = JaxSplatRenderer({"compositor": compositor, "tile_size": 8, "chunk_size": 16})
    mesh = _octahedron_sphere()
    capture = _capture(renderer, mesh)
    settings = {"iterations": 120, "min_gaussians": 400, "gaussians_per_pixel": 1.0, "log_every": 10, "init_color": "random",
                "holdout_every": 3, "lr_position": 1e-3, "lr_position_final": 1e-5, "select_count": False,
                "checkpoint_dir": str(tmp_path), "checkpoint_every": 60}
    progress = _Progress()
    fit = renderer.fit(capture, mesh, settings, Reporter(progress))
    losses = [e["loss"] for e in progress.events if "loss" in e]
    assert len(losses) == 12 and all(np.isfinite(losses))
    assert losses[-1] < 0.5 * losses[0]
    train_psnr = [e["psnr_train_view"] for e in progress.events if "psnr_train_view" in e]
    assert max(train_psnr[-3:]) > 27.0 and max(train_psnr[-3:]) > train_psnr[0] + 5.0
    g, f = fit.gaussians, fit.figures
    assert np.all(np.isin(mesh.face_labels[g.parent], [2]))  # garment only
    assert 0 < len(g) == f["gaussians"] < f["gaussians_selected"]
    assert f["gaussians_selected"] <= f["initial_gaussians"] - f["pruned_no_contribution"]
    assert f["pruned_no_contribution"] > 0
    assert f["iterations"] == 120 and f["sh_degree"] in (0, 1, 2, 3) and np.isfinite(f["psnr_heldout"])
    assert f["lr_factor"] == 10.0  # lr_scale = 0: sqrt(30000 / 120) clamped to 10 (fitplan.auto_lr_factor)
    assert f["backend"]["compositor"] == compositor
    # xla: one chunk capacity per image size (half, full), no growth; the fused kernel bins every call itself
    assert f["backend"]["chunk_capacity_changes"] == (2 if compositor == "xla" else 0)
    # the full model renders the training views well (PSNR against the images, sRGB)
    all_fit = renderer.fit(capture, mesh, dict(settings, keep="all", select_sh=False, prune_weight=0.0,
                                               checkpoint_dir=None))
    world = bind(all_fit.gaussians, mesh.vertices, mesh.faces)
    scores = [psnr(renderer.render(world, v.camera, v.background).color, v.image) for v in capture.views[:2]]
    assert min(scores) > 25.0
    # resuming: the checkpoint of the finished run (same settings) gives back the same Gaussians, no steps run
    resumed = _Progress()
    again = renderer.fit(capture, mesh, settings, Reporter(resumed))
    assert not [e for e in resumed.events if "loss" in e]
    np.testing.assert_array_equal(again.gaussians.means, fit.gaussians.means)
    np.testing.assert_array_equal(again.gaussians.sh, fit.gaussians.sh)


def test_contour_band_matches_opencv_morphology():
    cv2 = pytest.importorskip("cv2")
    from pgc.splats.fitplan import outside_band

    rng = np.random.default_rng(0)
    for band in (0.03, 0.1):
        m = (rng.random((64, 80)) < 0.1).astype(np.float32)
        m[20:50, 10:50] = 1.0
        m[:5] = 1.0                                   # touches the border: no erosion from outside
        side = max(1, int(round(band * 64)) | 1)
        k, mm = np.ones((side, side), np.uint8), (m > 0.5).astype(np.uint8)
        expected = (cv2.dilate(mm, k) == cv2.erode(mm, k)).astype(np.float32)
        np.testing.assert_array_equal(outside_band(m, band), expected)


def test_schedules_follow_the_fraction_of_the_fit():
    from pgc.roles.splat_renderer import FitSplatsSettings
    from pgc.splats.fitplan import position_lr_at, sh_degree_at

    s = FitSplatsSettings()
    assert position_lr_at(0.0, s) == pytest.approx(s.lr_position)
    assert position_lr_at(1.0, s) == pytest.approx(s.lr_position_final)
    assert position_lr_at(0.5, s) == pytest.approx(np.sqrt(s.lr_position * s.lr_position_final))
    assert [sh_degree_at(i / 30000, s) for i in (0, 499, 500, 1000, 1500, 29999)] == [0, 0, 1, 2, 3, 3]
    assert [sh_degree_at(i / 300, s) for i in (0, 4, 5, 10, 15)] == [0, 0, 1, 2, 3]  # interval scaled to 5 steps


def test_learning_rates_scale_and_slow_the_higher_sh_bands():
    from pgc.roles.splat_renderer import FitSplatsSettings
    from pgc.splats.fitplan import REST_LR_FACTOR, position_lr_at
    from pgc.splats.fit import learning_rates

    s = FitSplatsSettings()
    lrs = learning_rates(0.3, 2.0, 16, s)
    assert lrs["means"] == pytest.approx(2.0 * position_lr_at(0.3, s))
    assert lrs["opacity_logits"] == lrs["quats"] == lrs["log_scales"] == pytest.approx(2.0 * s.lr_other)
    assert lrs["sh"].shape == (16, 1) and lrs["sh"][0, 0] == pytest.approx(2.0 * s.lr_other)
    np.testing.assert_allclose(lrs["sh"][1:], 2.0 * s.lr_other * REST_LR_FACTOR)


def test_half_resolution_view_is_the_area_average():
    from pgc.splats.fitplan import half_resolution

    rng = np.random.default_rng(1)
    cam = _camera(0, 4)
    image, mask = rng.random((RES, RES, 3)).astype(np.float32), (rng.random((RES, RES)) > 0.5).astype(np.float32)
    half = half_resolution(View(cam, image, mask=mask, background=image[::-1].copy()))
    blocks = image.reshape(RES // 2, 2, RES // 2, 2, 3).mean((1, 3))
    np.testing.assert_allclose(half.image, blocks, atol=1e-6)
    np.testing.assert_allclose(half.mask, mask.reshape(RES // 2, 2, RES // 2, 2).mean((1, 3)), atol=1e-6)
    np.testing.assert_allclose(half.background, image[::-1].reshape(RES // 2, 2, RES // 2, 2, 3).mean((1, 3)),
                               atol=1e-6)
    assert (half.camera.width, half.camera.height) == (RES // 2, RES // 2)
    np.testing.assert_allclose(half.camera.K[:2], cam.K[:2] / 2)
    assert half_resolution(View(cam, image)).mask is None


def test_final_keep_drops_back_faces_then_keeps_the_garment():
    from pgc.roles.splat_renderer import FitSplatsSettings
    from pgc.splats.fitplan import backfacing_faces, final_keep

    mesh = _octahedron_sphere()
    cams = [_camera(0, 8)]                          # one camera: about half the sphere faces away from it
    parent = np.repeat(np.arange(len(mesh.faces)), 2)
    keep = np.ones(len(parent), bool)
    keep[::3] = False
    back = backfacing_faces(mesh, cams)
    assert 0 < back.sum() < len(back)
    figures = {}
    out = final_keep(keep, parent, mesh, cams, FitSplatsSettings(drop_backfacing=True), [2], figures)
    expected = keep & ~back[parent] & (mesh.face_labels[parent] == 2)
    np.testing.assert_array_equal(out, expected)
    assert figures == {"dropped_backfacing": int((keep & back[parent]).sum()),
                       "gaussians_selected": int((keep & ~back[parent]).sum()), "gaussians": int(expected.sum())}
    assert keep[1] and not keep[0]                  # the input is left as it was
    out_all = final_keep(keep, parent, mesh, cams, FitSplatsSettings(keep="all"), [2], {})
    np.testing.assert_array_equal(out_all, keep)


def test_training_views_come_in_epochs_and_coarse_first():
    from types import SimpleNamespace

    from pgc.splats.fit import training_view

    train = [SimpleNamespace(i=i, coarse=SimpleNamespace(i=-1 - i)) for i in range(5)]
    order, rng = [], np.random.default_rng(0)
    picks = [training_view(train, order, rng, False).i for _ in range(15)]
    assert all(sorted(picks[k:k + 5]) == list(range(5)) for k in (0, 5, 10)) and picks[:5] != picks[5:10]
    assert training_view(train, order, rng, True).i < 0  # the half-resolution copy
