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
def test_fit_converges_and_resumes(tmp_path):
    renderer = JaxSplatRenderer({"tile_size": 8, "chunk_size": 16})
    mesh = _octahedron_sphere()
    capture = _capture(renderer, mesh)
    settings = {"iterations": 120, "min_gaussians": 400, "gaussians_per_pixel": 1.0, "log_every": 10,
                "holdout_every": 3, "lr_position": 1e-3, "lr_position_final": 1e-5, "select_count": False,
                "checkpoint_dir": str(tmp_path), "checkpoint_every": 60}
    progress = _Progress()
    fit = renderer.fit(capture, mesh, settings, Reporter(progress))
    losses = [e["loss"] for e in progress.events if "loss" in e]
    assert len(losses) == 12 and all(np.isfinite(losses))
    assert losses[-1] < 0.5 * losses[0]
    train_psnr = [e["psnr_train_view"] for e in progress.events if "psnr_train_view" in e]
    assert max(train_psnr[-3:]) > 27.0 and train_psnr[0] < 22.0
    g = fit.gaussians
    assert 0 < len(g) < 400 and np.all(np.isin(mesh.face_labels[g.parent], [2]))  # garment only
    f = fit.figures
    assert f["iterations"] == 120 and f["sh_degree"] in (0, 1, 2, 3) and np.isfinite(f["psnr_heldout"])
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
