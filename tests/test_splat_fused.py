"""The fused splat kernel (backend "fused"): images against the float64 reference, gradients of all five inputs
(rotation matrices included) against float64 finite differences, agreement with the pure-torch path,
hard cases, and determinism over thread counts."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import overlapping_gaussians as _scene, tilted_camera
from pgc.splats import fused
from pgc.splats.reference import render_reference
from pgc.types import Camera, WorldGaussians

torch = pytest.importorskip("torch")

from pgc.splats.quaternion import quat_to_rotmat  # noqa: E402
from pgc_torch.splat.rasterizer import rasterize  # noqa: E402
from pgc_torch.splat.renderer import TorchSplatRenderer  # noqa: E402

FIELDS = ("means", "rotmats", "scales", "opacities", "sh")
pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module", autouse=True)
def _kernel_builds():
    assert fused.available(), "the fused splat kernel must build here (g++ with OpenMP)"


def _camera(w: int = 32, h: int = 24, f: float = 40.0) -> Camera:
    return tilted_camera(w, h, f, skew=0.3)


def _hard_scene() -> WorldGaussians:
    """Tiny, huge and clamped scales, a zero quaternion, Gaussians behind the camera, at and across the near
    plane, a grazing (edge-on) disc, and opacities at 0, just under 1/255 and at the 0.99 clamp."""
    rng = np.random.default_rng(3)
    cases = [
        ([0.0, 0.0, 1.0], [1e-9, 1e-9, 1e-9], [1, 0, 0, 0], 0.7),
        ([0.1, 0.0, 1.2], [1e3, 1e3, 1e3], [1, 0, 0, 0], 0.3),
        ([0.0, 0.1, 1.5], [1e9, 1e-9, 1.0], [0, 0, 0, 0], 0.5),
        ([0.0, 0.0, -1.0], [0.1, 0.1, 0.1], [1, 0, 0, 0], 0.9),
        ([0.0, 0.0, 0.011 - 0.1 * np.cos(0.1)], [0.5, 0.5, 0.5], [1, 0, 0, 0], 0.6),
        ([0.05, -0.05, 0.02], [0.3, 0.3, 0.3], [0.3, 0.2, 0.9, 0.1], 0.8),
        ([-0.1, 0.05, 1.1], [0.2, 1e-7, 0.2], [0.7071, 0.7071, 0, 0], 0.95),   # edge-on disc
        ([0.05, 0.05, 1.3], [0.05, 0.05, 0.05], [1, 0, 0, 0], 0.0),
        ([-0.05, -0.05, 1.3], [0.05, 0.05, 0.05], [1, 0, 0, 0], 0.99 / 255.0),
        ([0.02, -0.02, 0.9], [0.03, 0.04, 0.05], [1, 0, 0, 0], 1.0),
    ]
    return WorldGaussians(means=np.array([c[0] for c in cases], float), quats=np.array([c[2] for c in cases], float),
                          scales=np.array([c[1] for c in cases], float), opacities=np.array([c[3] for c in cases]),
                          sh=rng.normal(0, 0.4, (len(cases), 16, 3)))


def _params(world: WorldGaussians, dtype) -> list:
    """Leaf tensors (means, rotmats, scales, opacities, sh): rotation matrices from the quaternions in float64."""
    rot = quat_to_rotmat(torch.tensor(np.asarray(world.quats), dtype=torch.float64))
    return [torch.tensor(np.asarray(x), dtype=dtype, requires_grad=True)
            for x in (world.means, rot.numpy(), world.scales, world.opacities, world.sh)]


def _value(params, cam, bg, weights, backend: str, threads: int = 2, sh_degree=None):
    color, alpha, depth = rasterize(*params, cam, bg, sh_degree=sh_degree, backend=backend, threads=threads)
    return (color * weights[0]).sum() + (alpha * weights[1]).sum() + (depth * weights[2]).sum()


def _weights(h: int, w: int, seed: int, depth: bool = True):
    rng = np.random.default_rng(seed)
    wc, wa, wd = rng.normal(size=(h, w, 3)), rng.normal(size=(h, w)), rng.normal(size=(h, w))
    return wc, wa, wd if depth else np.zeros((h, w))


@pytest.mark.agreement
@pytest.mark.parametrize(("seed", "degree"), [(0, None), (1, None), (2, 0), (3, 1), (4, 2)])
def test_images_match_reference(seed, degree):
    world, cam = _scene(150, seed), _camera()
    bg = np.random.default_rng(seed).uniform(size=(24, 32, 3))
    ref = render_reference(world, cam, background=bg, sh_degree=degree)
    out = TorchSplatRenderer({"compositor": "fused", "threads": 2}).render(world, cam, bg, degree)
    for name in ("color", "alpha", "depth"):
        value = getattr(out, name)
        assert value.dtype == np.float32 and np.all(np.isfinite(value)), name
    np.testing.assert_allclose(out.color, ref.color, atol=1e-5)
    np.testing.assert_allclose(out.alpha, ref.alpha, atol=1e-5)
    np.testing.assert_allclose(out.depth, ref.depth, rtol=1e-5, atol=1e-5 * float(ref.depth.max()))


def test_hard_cases_match_reference_and_gradients_stay_finite():
    world, cam = _hard_scene(), _camera()
    bg = np.array([0.1, 0.2, 0.3])
    ref = render_reference(world, cam, background=bg)
    for dtype in (torch.float32, torch.float64):
        params = _params(world, dtype)
        color, alpha, depth = rasterize(*params, cam, bg, backend="fused", threads=2)
        np.testing.assert_allclose(color.detach().numpy(), ref.color, atol=1e-5)
        np.testing.assert_allclose(alpha.detach().numpy(), ref.alpha, atol=1e-5)
        np.testing.assert_allclose(depth.detach().numpy(), ref.depth, rtol=1e-5, atol=1e-5)
        (color.sum() + alpha.sum() + depth.sum()).backward()
        for name, p in zip(FIELDS, params):
            assert torch.isfinite(p.grad).all(), (dtype, name)


def test_float32_gradients_match_float64_finite_differences_for_every_input():
    """Per input, the directional derivative along a random direction by central differences of a float64
    oracle against the fused float32 gradient: the per-pixel reference for means, scales, opacities and SH
    (perturbing the quaternion-free fields of the world Gaussians), the float64 torch path (torch projection,
    torch compositing) for the rotation matrices, which the reference cannot take."""
    world, cam = _scene(60, 11, sh_k=4), _camera(24, 18)
    wc, wa, _ = _weights(18, 24, 12)
    rot = _params(world, torch.float64)[1].detach().numpy()
    base = {"means": np.asarray(world.means, float), "rotmats": rot, "scales": np.asarray(world.scales, float),
            "opacities": np.asarray(world.opacities, float), "sh": np.asarray(world.sh, float)}
    zeros = torch.zeros(18, 24, dtype=torch.float64)

    def oracle(values: dict, name: str) -> float:
        if name == "rotmats":
            params = [torch.tensor(values[f]) for f in FIELDS]
            return float(_value(params, cam, None, [torch.tensor(wc), torch.tensor(wa), zeros], "torch"))
        w = WorldGaussians(values["means"], world.quats, values["scales"], values["opacities"], values["sh"])
        out = render_reference(w, cam)
        return float((out.color * wc).sum() + (out.alpha * wa).sum())

    params = _params(world, torch.float32)
    weights = [torch.tensor(wc, dtype=torch.float32), torch.tensor(wa, dtype=torch.float32), zeros.float()]
    grads = dict(zip(FIELDS, torch.autograd.grad(_value(params, cam, None, weights, "fused"), params)))
    rng = np.random.default_rng(13)
    h = 1e-7
    for name in FIELDS:
        direction = rng.normal(size=base[name].shape)
        plus, minus = dict(base), dict(base)
        plus[name], minus[name] = base[name] + h * direction, base[name] - h * direction
        fd = (oracle(plus, name) - oracle(minus, name)) / (2 * h)
        analytic = float((grads[name].double() * torch.as_tensor(direction)).sum())
        assert analytic == pytest.approx(fd, rel=1e-3), name


def test_float64_gradcheck_of_all_five_inputs():
    """torch.autograd.gradcheck (random projections) of the fused function in float64, colour, alpha and depth."""
    world, cam = _scene(12, 5), _camera(16, 12, f=20.0)
    wc, wa, wd = (torch.tensor(x) for x in _weights(12, 16, 6))
    bg = torch.tensor(np.random.default_rng(7).uniform(size=(12, 16, 3)))

    def fn(*params):
        return _value(list(params), cam, bg, [wc, wa, wd], "fused")

    assert torch.autograd.gradcheck(fn, _params(world, torch.float64), eps=1e-8, atol=1e-5, rtol=1e-3,
                                    fast_mode=True)


@pytest.mark.agreement
@pytest.mark.parametrize("seed", [0, 1])
def test_fused_and_torch_agree(seed):
    """Images (float32) and gradients of every input (float32 and float64) of the two paths."""
    world, cam = _scene(120, seed), _camera()
    bg = torch.tensor(np.random.default_rng(seed).uniform(size=(24, 32, 3)))
    weights = [torch.tensor(x) for x in _weights(24, 32, 20 + seed)]
    results = {}
    for backend in ("fused", "torch"):
        for dtype in (torch.float32, torch.float64):
            params = _params(world, dtype)
            images = rasterize(*params, cam, bg.to(dtype), backend=backend, threads=2)
            value = sum((x * w.to(dtype)).sum() for x, w in zip(images, weights))
            results[backend, dtype] = ([x.detach().double() for x in images],
                                       [g.double() for g in torch.autograd.grad(value, params)])
    oracle_images, oracle_grads = results["torch", torch.float64]
    for key, (images, grads) in results.items():
        tol_img = 1e-5 if key[1] == torch.float32 else 1e-12
        tol_grad = 1e-3 if key[1] == torch.float32 else 1e-9
        for x, y in zip(images, oracle_images):
            assert float((x - y).abs().max()) <= tol_img * max(1.0, float(y.abs().max())), key
        for name, g, r in zip(FIELDS, grads, oracle_grads):
            assert float((g - r).norm() / r.norm()) < tol_grad, (key, name)


def test_thread_count_changes_no_byte_of_images_or_gradients():
    # 128 x 112 px, 2000 Gaussians: large enough that the kernel starts all 3 threads (one per 1024 pixels)
    world, cam = _scene(2000, 4), _camera(128, 112)
    weights = [torch.tensor(x, dtype=torch.float32) for x in _weights(112, 128, 9)]
    outputs = []
    for threads in (1, 2, 3):
        params = _params(world, torch.float32)
        images = rasterize(*params, cam, None, backend="fused", threads=threads, tile=8)
        value = sum((x * w).sum() for x, w in zip(images, weights))
        outputs.append([x.detach().numpy().tobytes() for x in images] +
                       [g.numpy().tobytes() for g in torch.autograd.grad(value, params)])
    assert outputs[0] == outputs[1] == outputs[2]


@pytest.mark.parametrize("tile", [4, 12, 16, 24])
def test_tile_size_changes_no_pixel(tile):
    world, cam = _scene(100, 8), _camera(40, 30)
    ref = rasterize(*_params(world, torch.float32), cam, None, backend="fused", tile=16)[0]
    out = rasterize(*_params(world, torch.float32), cam, None, backend="fused", tile=tile)[0]
    np.testing.assert_array_equal(out.detach().numpy(), ref.detach().numpy())


def test_empty_and_fully_culled_scenes_give_background_and_zero_gradients():
    bg = np.full((24, 32, 3), 0.25)
    for world in (_scene(0, 0), WorldGaussians(np.array([[0.0, 0.0, -2.0]]), np.array([[1.0, 0, 0, 0]]),
                                               np.array([[0.1, 0.1, 0.1]]), np.array([0.9]),
                                               np.zeros((1, 16, 3)))):
        params = _params(world, torch.float32)
        color, alpha, depth = rasterize(*params, _camera(), bg, backend="fused")
        np.testing.assert_array_equal(color.detach().numpy(), bg.astype(np.float32))
        np.testing.assert_array_equal(alpha.detach().numpy(), 0)
        if len(world.means):
            (color.sum() + alpha.sum()).backward()
            assert all(float(p.grad.abs().max()) == 0.0 for p in params)


def test_auto_picks_the_fused_path_and_stats_count_the_work():
    assert TorchSplatRenderer({"compositor": "auto"}).compositor == "fused"
    world, cam = _scene(50, 2), _camera()
    p = [x.detach() for x in _params(world, torch.float32)]
    stats = fused.render_stats([x.numpy() for x in p], cam, count=16)
    assert 0 < stats["visible"] <= 50 and stats["entries"] >= stats["visible"] and stats["pairs"] > 0


def test_opacity_aware_binning_drops_tiles_but_no_pixel():
    """Thin discs turned 45 degrees in the image and faint Gaussians: the kernel bins each Gaussian only to the
    tiles its alpha >= 1/255 ellipse reaches, far fewer than the tiles of the contract's footprint boxes, and the
    image still matches the float64 reference (which composites every pixel of every box) and the cpp path
    (box binning); gradients match the cpp path."""
    from pgc.splats.projection import project

    rng = np.random.default_rng(21)
    n = 40
    angle = np.pi / 4
    quats = np.tile([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)], (n, 1)) + rng.normal(0, 0.05, (n, 4))
    world = WorldGaussians(means=np.c_[rng.uniform(-0.3, 0.3, n), rng.uniform(-0.2, 0.2, n), rng.uniform(0.9, 1.3, n)],
                           quats=quats, scales=np.c_[rng.uniform(0.08, 0.2, n), np.full(n, 0.004), np.full(n, 0.004)],
                           opacities=rng.uniform(0.01, 0.9, n), sh=rng.normal(0, 0.4, (n, 16, 3)))
    cam, tile = _camera(64, 48, f=60.0), 4
    proj = project(world, cam)
    box_tiles = 0
    for (u, v), r in zip(proj.means2d, proj.radii):
        x0, x1 = max(np.ceil(u - r - 0.5), 0), min(np.floor(u + r - 0.5), 63)
        y0, y1 = max(np.ceil(v - r - 0.5), 0), min(np.floor(v + r - 0.5), 47)
        if r > 0 and x0 <= x1 and y0 <= y1:
            box_tiles += int((x1 // tile - x0 // tile + 1) * (y1 // tile - y0 // tile + 1))
    params = _params(world, torch.float32)
    stats = fused.render_stats([p.detach().numpy() for p in params], cam, count=16, tile=tile)
    assert 0 < stats["entries"] < 0.6 * box_tiles
    ref = render_reference(world, cam)
    weights = [torch.tensor(x, dtype=torch.float32) for x in _weights(48, 64, 22)]
    results = {}
    for backend in ("fused", "torch"):
        params = _params(world, torch.float32)
        images = rasterize(*params, cam, None, backend=backend, tile=tile, threads=2)
        value = sum((x * w).sum() for x, w in zip(images, weights))
        results[backend] = ([x.detach().numpy() for x in images], torch.autograd.grad(value, params))
    color, alpha, _ = results["fused"][0]
    np.testing.assert_allclose(color, ref.color, atol=1e-5)
    np.testing.assert_allclose(alpha, ref.alpha, atol=1e-5)
    # both float32: the cpp path rounds the screen means to float32 (~2e-6 px here), which these sub-pixel-thin
    # discs (alpha slope up to ~1/DILATION per px) turn into up to ~1e-5 of alpha; each is within 1e-5 of float64
    for x, y in zip(results["fused"][0], results["torch"][0]):
        np.testing.assert_allclose(x, y, atol=2e-5 * max(1.0, float(np.abs(y).max())))
    for name, g, r in zip(FIELDS, results["fused"][1], results["torch"][1]):
        assert float((g - r).norm() / r.norm()) < 1e-3, name
