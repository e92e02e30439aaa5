"""The torch splat renderer against the float64 reference, float64 gradient checks, and hard cases."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import overlapping_gaussians as _scene, tilted_camera as _camera
from pgc.splats import fused as fused_kernel
from pgc.splats.binding import bind as np_bind, bind_arrays
from pgc.splats.quaternion import quat_to_rotmat
from pgc.splats.reference import render_reference
from pgc.types import Camera, GaussianSet, WorldGaussians

torch = pytest.importorskip("torch")

from pgc_torch.splat.rasterizer import rasterize  # noqa: E402
from pgc_torch.splat.renderer import TorchSplatRenderer  # noqa: E402

COMPOSITORS = ["fused", "torch"]
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module", autouse=True)
def _kernel_builds():
    assert fused_kernel.available(), "the fused splat kernel must build here (g++ with OpenMP)"


def _assert_matches_reference(world: WorldGaussians, cam: Camera, background, compositor: str,
                              sh_degree: int | None = None, atol: float = 1e-5) -> None:
    ref = render_reference(world, cam, background=background, sh_degree=sh_degree)
    out = TorchSplatRenderer({"compositor": compositor, "threads": 2}).render(world, cam, background, sh_degree)
    for name in ("color", "alpha", "depth"):
        value = getattr(out, name)
        assert value.dtype == np.float32 and np.all(np.isfinite(value)), name
    np.testing.assert_allclose(out.color, ref.color, atol=atol)
    np.testing.assert_allclose(out.alpha, ref.alpha, atol=atol)
    np.testing.assert_allclose(out.depth, ref.depth, rtol=atol, atol=atol * max(1.0, float(ref.depth.max())))


@pytest.mark.parametrize("compositor", COMPOSITORS)
@pytest.mark.parametrize("seed", [0, 1])
def test_images_match_reference_on_overlapping_scenes(compositor, seed):
    bg = np.random.default_rng(seed).uniform(size=(24, 32, 3))
    _assert_matches_reference(_scene(120, seed), _camera(), bg, compositor)


@pytest.mark.parametrize("degree", [0, 1, 2])
def test_lower_sh_degrees_match_reference(degree):
    _assert_matches_reference(_scene(40, 7), _camera(), np.array([0.2, 0.3, 0.1]), "torch", sh_degree=degree)


def _hard_scene() -> WorldGaussians:
    rng = np.random.default_rng(3)
    cases = [
        ([0.0, 0.0, 1.0], [1e-9, 1e-9, 1e-9], [1, 0, 0, 0]),        # tiny scale
        ([0.1, 0.0, 1.2], [1e3, 1e3, 1e3], [1, 0, 0, 0]),          # huge scale, covers the whole image
        ([0.0, 0.1, 1.5], [1e9, 1e-9, 1.0], [0, 0, 0, 0]),         # clamped scale, zero quaternion
        ([0.0, 0.0, -1.0], [0.1, 0.1, 0.1], [1, 0, 0, 0]),         # behind the camera
        ([0.0, 0.0, 0.011 - 0.1 * np.cos(0.1) + 0.0], [0.5, 0.5, 0.5], [1, 0, 0, 0]),  # near the near plane
        ([0.05, -0.05, 0.02], [0.3, 0.3, 0.3], [0.3, 0.2, 0.9, 0.1]),  # straddles the near plane
    ]
    means = np.array([c[0] for c in cases])
    return WorldGaussians(means=means, quats=np.array([c[2] for c in cases], float),
                          scales=np.array([c[1] for c in cases]), opacities=np.linspace(0.3, 0.95, len(cases)),
                          sh=rng.normal(0, 0.4, (len(cases), 16, 3)))


@pytest.mark.parametrize("compositor", COMPOSITORS)
def test_hard_cases_match_reference_and_stay_finite(compositor):
    _assert_matches_reference(_hard_scene(), _camera(), np.array([0.1, 0.2, 0.3]), compositor)


@pytest.mark.parametrize("compositor", COMPOSITORS)
def test_empty_scene_gives_background(compositor):
    empty = WorldGaussians(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3)))
    bg = np.full((24, 32, 3), 0.25, np.float32)
    out = TorchSplatRenderer({"compositor": compositor}).render(empty, _camera(), bg)
    np.testing.assert_array_equal(out.color, bg)
    np.testing.assert_array_equal(out.alpha, 0)


def _torch_world(world: WorldGaussians, dtype) -> list:
    return [torch.tensor(np.asarray(world.means), dtype=dtype, requires_grad=True),
            torch.tensor(np.asarray(world.quats), dtype=dtype, requires_grad=True),
            torch.tensor(np.asarray(world.scales), dtype=dtype, requires_grad=True),
            torch.tensor(np.asarray(world.opacities), dtype=dtype, requires_grad=True),
            torch.tensor(np.asarray(world.sh), dtype=dtype, requires_grad=True)]


def _weighted_render(params, cam, bg, weights, compositor, threads=2):
    means, quats, scales, opac, sh = params
    color, alpha, depth = rasterize(means, quat_to_rotmat(quats), scales, opac, sh, cam, bg, backend=compositor,
                                    threads=threads)
    wc, wa, wd = weights
    return (color * wc).sum() + (alpha * wa).sum() + (depth * wd).sum()


@pytest.mark.agreement
@pytest.mark.parametrize("seed", [0, 1])
def test_float32_gradients_match_float64_and_both_compositors(seed):
    world, cam = _scene(120, seed), _camera()
    rng = np.random.default_rng(10 + seed)
    bg = rng.uniform(size=(24, 32, 3))
    weights = [torch.tensor(rng.normal(size=s)) for s in ((24, 32, 3), (24, 32), (24, 32))]
    grads = {}
    for dtype, comp in [(torch.float64, "torch"), (torch.float32, "fused"), (torch.float32, "torch")]:
        params = _torch_world(world, dtype)
        w = [x.to(dtype) for x in weights]
        value = _weighted_render(params, cam, torch.tensor(bg, dtype=dtype), w, comp)
        grads[dtype, comp] = torch.autograd.grad(value, params)
    names = ("means", "quats", "scales", "opacities", "sh")
    for key in [(torch.float32, "fused"), (torch.float32, "torch")]:
        for name, g32, g64 in zip(names, grads[key], grads[torch.float64, "torch"]):
            err = (g32.double() - g64).norm() / g64.norm()
            assert err < 1e-3, (key, name, float(err))


def _small_mesh_scene(seed: int, degenerate: bool):
    rng = np.random.default_rng(seed)
    v = np.c_[rng.uniform(-0.3, 0.3, 8), rng.uniform(-0.2, 0.2, 8), rng.uniform(1.0, 1.5, 8)]
    faces = [[0, 1, 2], [2, 3, 4], [4, 5, 6], [5, 6, 7]] + ([[1, 1, 3], [0, 3, 0]] if degenerate else [])
    n = 8
    g = GaussianSet(parent=rng.integers(0, len(faces), n), means=rng.normal(0, 0.3, (n, 3)),
                    quats=rng.normal(size=(n, 4)), log_scales=rng.uniform(-1.5, -0.5, (n, 3)),
                    opacity_logits=rng.uniform(-1, 2, n), sh=rng.normal(0, 0.3, (n, 16, 3)))
    return v, np.array(faces), g


@pytest.mark.parametrize(("compositor", "fast"), [pytest.param("torch", False, marks=pytest.mark.slow),
                                                   ("fused", True), ("torch", True)])
def test_finite_difference_gradients_of_every_parameter_and_vertices(compositor, fast):
    """float64 gradcheck through the binding: local means, quaternions, log-scales, opacity logits, SH and the
    vertex positions. The image has measure-zero discontinuities (footprint box, 1/255 cut), so the step is
    small (1e-8) and the scene fixed. ``fast``: gradcheck's random-projection variant; the full Jacobian
    check is marked slow."""
    v, f, g = _small_mesh_scene(2, degenerate=False)
    cam = Camera(K=[[30, 0, 8], [0, 30, 6], [0, 0, 1]], R=np.eye(3), t=[0, 0, 0], width=16, height=12)
    rng = np.random.default_rng(5)
    bg = torch.tensor(rng.uniform(size=(12, 16, 3)))
    weights = [torch.tensor(rng.normal(size=s)) for s in ((12, 16, 3), (12, 16), (12, 16))]
    parent, faces = torch.as_tensor(g.parent), torch.as_tensor(f)
    inputs = [torch.tensor(np.asarray(x, np.float64), requires_grad=True)
              for x in (g.means, g.quats, g.log_scales, g.opacity_logits, g.sh, v)]

    def fn(means, quats, log_scales, logits, sh, verts):
        m, rot, s, o = bind_arrays(parent, means, quats, log_scales, logits, verts, faces)
        color, alpha, depth = rasterize(m, rot, s, o, sh, cam, bg, backend=compositor)
        return (color * weights[0]).sum() + (alpha * weights[1]).sum() + (depth * weights[2]).sum()

    assert torch.autograd.gradcheck(fn, inputs, eps=1e-8, atol=1e-5, rtol=1e-3, fast_mode=fast)


def test_gradients_are_finite_on_hard_cases_and_degenerate_triangles():
    v, f, g = _small_mesh_scene(4, degenerate=True)
    v = np.vstack([v, [[0.0, 0.0, 1.0]] * 3])
    f = np.vstack([f, [[8, 9, 10]]])  # a triangle collapsed to a point
    g = GaussianSet(parent=np.r_[g.parent, len(f) - 1, len(f) - 1], means=np.vstack([g.means, [[0, 0, 0]] * 2]),
                    quats=np.vstack([g.quats, [[0, 0, 0, 0]] * 2]), log_scales=np.vstack([g.log_scales, [[-30] * 3, [30] * 3]]),
                    opacity_logits=np.r_[g.opacity_logits, 40.0, -40.0], sh=np.concatenate([g.sh, np.zeros((2, 16, 3))]))
    cam = Camera(K=[[30, 0, 8], [0, 30, 6], [0, 0, 1]], R=np.eye(3), t=[0, 0, -0.99], width=16, height=12)
    for dtype in (torch.float32, torch.float64):
        inputs = [torch.tensor(np.asarray(x), dtype=dtype, requires_grad=True)
                  for x in (g.means, g.quats, g.log_scales, g.opacity_logits, g.sh, v)]
        m, rot, s, o = bind_arrays(torch.as_tensor(g.parent), *inputs[:4], inputs[5], torch.as_tensor(f))
        color, alpha, depth = rasterize(m, rot, s, o, inputs[4], cam, None)
        assert all(torch.isfinite(x).all() for x in (color, alpha, depth))
        (color.sum() + alpha.sum() + depth.sum()).backward()
        for x in inputs:
            assert torch.isfinite(x.grad).all()
    world = np_bind(g, v, f)
    _assert_matches_reference(world, cam, None, "torch")


def test_registered_and_built_through_the_registry():
    from pgc.registry import default_registry

    renderer = default_registry().create("splat_renderer", "torch", {"compositor": "auto"})
    assert isinstance(renderer, TorchSplatRenderer) and renderer.compositor == "fused"


def test_kernel_build_failure_is_reported_and_auto_falls_back(tmp_path, monkeypatch):
    monkeypatch.setenv("PGC_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-compiler"))
    with pytest.raises(fused_kernel.NativeLibraryUnavailable):
        fused_kernel.build()
    monkeypatch.setattr(fused_kernel, "available", lambda: False)
    assert TorchSplatRenderer({"compositor": "auto"}).compositor == "torch"


def test_kernel_threads_do_not_change_the_image():
    world, cam = _scene(200, 4), _camera()
    one = TorchSplatRenderer({"threads": 1}).render(world, cam)
    two = TorchSplatRenderer({"threads": 2}).render(world, cam)
    np.testing.assert_array_equal(one.color, two.color)


def test_float32_gradient_matches_reference_finite_differences():
    """Directional derivatives of the float64 reference (central differences) against the float32 torch
    gradient on an overlapping scene, for random directions in the space of all world parameters."""
    world, cam = _scene(60, 11, sh_k=4), _camera(24, 18)
    rng = np.random.default_rng(12)
    wc, wa = rng.normal(size=(18, 24, 3)), rng.normal(size=(18, 24))
    fields = ("means", "quats", "scales", "opacities", "sh")

    def ref_value(w: WorldGaussians) -> float:
        out = render_reference(w, cam)
        return float((out.color * wc).sum() + (out.alpha * wa).sum())

    params = _torch_world(world, torch.float32)
    weights = [torch.tensor(wc, dtype=torch.float32), torch.tensor(wa, dtype=torch.float32),
               torch.zeros(18, 24)]
    grads = torch.autograd.grad(_weighted_render(params, cam, None, weights, "torch"), params)
    h = 1e-7
    for _ in range(3):
        direction = {f: rng.normal(size=np.shape(getattr(world, f))) for f in fields}
        plus = WorldGaussians(**{f: np.asarray(getattr(world, f), float) + h * direction[f] for f in fields})
        minus = WorldGaussians(**{f: np.asarray(getattr(world, f), float) - h * direction[f] for f in fields})
        fd = (ref_value(plus) - ref_value(minus)) / (2 * h)
        analytic = sum(float((g.double() * torch.as_tensor(direction[f])).sum()) for g, f in zip(grads, fields))
        assert analytic == pytest.approx(fd, rel=1e-3)


def _ssim_direct(x: np.ndarray, y: np.ndarray) -> float:
    """SSIM of (H, W, 3) images in float64 with the full 11 x 11 window and zero padding, pixel by pixel."""
    t = np.arange(11) - 5
    g = np.exp(-t * t / (2 * 1.5 ** 2))
    w = np.outer(g, g) / g.sum() ** 2
    h, wd = x.shape[:2]

    def blur(a: np.ndarray) -> np.ndarray:
        pad = np.pad(a, ((5, 5), (5, 5), (0, 0)))
        return sum(w[i, j] * pad[i:i + h, j:j + wd] for i in range(11) for j in range(11))

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return float((((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean())


def test_separable_ssim_equals_the_full_window():
    from pgc.metrics.ssim import mean_ssim as ssim

    rng = np.random.default_rng(3)
    x = rng.uniform(size=(23, 17, 3))
    y = np.clip(x + 0.1 * rng.normal(size=x.shape), 0.0, 1.0)
    got = float(ssim(torch.tensor(x), torch.tensor(y)))
    assert got == pytest.approx(_ssim_direct(x, y), abs=1e-12)
    assert float(ssim(torch.tensor(x), torch.tensor(x))) == pytest.approx(1.0, abs=1e-12)
