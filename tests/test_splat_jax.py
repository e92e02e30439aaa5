"""The JAX splat renderer: float64 reference, torch, float64 finite differences, hard cases, binding."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import overlapping_gaussians as _scene, tilted_camera as _camera
from pgc.splats.binding import bind as np_bind
from pgc.splats.quaternion import quat_to_rotmat as np_quat_to_rotmat
from pgc.splats.reference import render_reference
from pgc.types import GaussianSet, WorldGaussians

jax = pytest.importorskip("jax")
import jax.numpy as jnp  # noqa: E402

from pgc.splats.binding import bind_arrays as bind, triangle_frames  # noqa: E402
from pgc_jax.splat.fused import camera_bits, fused_render  # noqa: E402
from pgc.splats.quaternion import quat_to_rotmat  # noqa: E402
from pgc_jax.splat.render import camera_arrays, make_bins, render_bound  # noqa: E402
from pgc_jax.splat.renderer import JaxSplatRenderer  # noqa: E402

W, H = 32, 24
COMPOSITORS = ["xla", "fused"]


def _assert_matches_reference(world, cam, background, options=None, sh_degree=None, atol=1e-5):
    ref = render_reference(world, cam, background=background, sh_degree=sh_degree)
    out = JaxSplatRenderer(options).render(world, cam, background, sh_degree)
    for name in ("color", "alpha", "depth"):
        value = getattr(out, name)
        assert value.dtype == np.float32 and value.shape[:2] == (cam.height, cam.width), name
        assert np.all(np.isfinite(value)), name
    np.testing.assert_allclose(out.color, ref.color, atol=atol)
    np.testing.assert_allclose(out.alpha, ref.alpha, atol=atol)
    np.testing.assert_allclose(out.depth, ref.depth, rtol=atol, atol=atol * max(1.0, float(ref.depth.max())))
    return out, ref


@pytest.mark.parametrize("options", [{"compositor": "xla", "tile_size": 8, "chunk_size": 8},
                                     {"compositor": "xla", "tile_size": 16, "chunk_size": 32},
                                     {"compositor": "fused", "threads": 2}])
def test_images_match_reference_on_overlapping_scenes(options):
    bg = np.random.default_rng(5).uniform(size=(H, W, 3))
    out, ref = _assert_matches_reference(_scene(120, 0), _camera(), bg, options)
    assert ref.alpha.max() > 0.99 and ref.alpha.min() < 0.5  # saturated and sparse regions both present


@pytest.mark.parametrize("compositor", COMPOSITORS)
@pytest.mark.parametrize("degree", [0, 2])
def test_lower_sh_degrees_match_reference(degree, compositor):
    _assert_matches_reference(_scene(120, 7), _camera(), np.array([0.2, 0.3, 0.1]), {"compositor": compositor},
                              sh_degree=degree)


def test_fused_backward_is_the_same_after_its_workspace_is_used_or_evicted():
    """The fused VJP keeps each forward's workspace for its backward; a second backward, or one whose workspace
    was evicted by KEEP later forwards, re-runs the forward and gives the same bytes."""
    from pgc_jax.splat import fused

    world, cam = _scene(80, 3), _camera()
    arrays = [jnp.asarray(np.asarray(x), jnp.float32) for x in (world.means, world.scales, world.opacities,
                                                                  world.sh)]
    rot = jnp.asarray(np_quat_to_rotmat(world.quats), jnp.float32)
    bits, bg = jnp.asarray(camera_bits(cam, 0.01)), jnp.zeros((H, W, 3), jnp.float32)

    def image(m):
        return fused_render(m, rot, *arrays[1:], bits, bg, height=H, width=W, count=16)[0]

    _, vjp = jax.vjp(image, arrays[0])
    cot = jnp.asarray(np.random.default_rng(1).normal(size=(H, W, 3)), jnp.float32)
    first = np.asarray(vjp(cot)[0])
    again = np.asarray(vjp(cot)[0])                     # its workspace was taken by the first backward
    _, later = jax.vjp(image, arrays[0])
    for _ in range(fused.KEEP + 1):
        jax.vjp(image, arrays[0])                       # evicts ``later``'s workspace
    evicted = np.asarray(later(cot)[0])
    assert np.abs(first).max() > 0
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first, evicted)


def test_auto_picks_the_fused_kernel_on_the_cpu():
    assert JaxSplatRenderer().compositor == "fused"
    assert JaxSplatRenderer({"compositor": "xla"}).compositor == "xla"


def test_binding_matches_numpy_including_degenerate_triangles():
    rng = np.random.default_rng(2)
    V = rng.normal(size=(9, 3))
    V[7] = V[6]                                   # repeated vertex
    V[8] = 0.5 * (V[0] + V[1])                    # collinear with 0 and 1
    F = np.array([[0, 1, 2], [2, 3, 4], [5, 6, 7], [0, 8, 1], [3, 3, 3], [4, 2, 1]])
    g = GaussianSet(rng.integers(0, len(F), 40), rng.normal(size=(40, 3)), rng.normal(size=(40, 4)),
                    rng.normal(size=(40, 3)), rng.normal(size=40), rng.normal(size=(40, 4, 3)))
    g.quats[:3] = 0.0                             # zero quaternions mean identity
    ref = np_bind(g, V, F)
    jbind = jax.jit(bind)
    with jax.enable_x64(True):
        b = jbind(jnp.asarray(g.parent), *(jnp.asarray(x, jnp.float64) for x in
                                           (g.means, g.quats, g.log_scales, g.opacity_logits, V)), jnp.asarray(F))
        np.testing.assert_allclose(np.asarray(b.means), ref.means, atol=1e-12)
        np.testing.assert_allclose(np.asarray(b.rotmats), np_quat_to_rotmat(ref.quats), atol=1e-12)
        np.testing.assert_allclose(np.asarray(b.scales), ref.scales, rtol=1e-12)
        np.testing.assert_allclose(np.asarray(b.opacities), ref.opacities, rtol=1e-12)
    b32 = jbind(jnp.asarray(g.parent), *(jnp.asarray(x, jnp.float32) for x in
                                         (g.means, g.quats, g.log_scales, g.opacity_logits, V)), jnp.asarray(F))
    np.testing.assert_allclose(np.asarray(b32.means), ref.means, rtol=1e-5, atol=1e-5)

    def total(v):
        tau, R, k = triangle_frames(v, jnp.asarray(F))
        return jnp.sum(tau) + jnp.sum(R * jnp.arange(9.0).reshape(3, 3)) + jnp.sum(k)

    grad = jax.jit(jax.grad(total))(jnp.asarray(V, jnp.float32))
    assert np.all(np.isfinite(np.asarray(grad)))  # degenerate faces: finite gradients too


GRAD_CAM = _camera(24, 20, 30.0)


def _grad_problem(dtype, compositor="xla", seed=1, n=60):
    """A random mesh-embedded scene: (jitted loss(params) at fixed bins, params, numpy inputs)."""
    rng = np.random.default_rng(seed)
    cam = GRAD_CAM
    V = rng.uniform([-0.3, -0.3, 0.9], [0.3, 0.3, 1.3], (12, 3))
    F = rng.integers(0, 12, (14, 3))
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    data = {"means": rng.normal(0, 0.3, (n, 3)), "quats": rng.normal(size=(n, 4)),
            "log_scales": rng.normal(-1.0, 0.3, (n, 3)), "opacity_logits": rng.normal(0, 1, n),
            "sh": rng.normal(0, 0.3, (n, 16, 3)), "vertices": V}
    params = {k: jnp.asarray(v, dtype) for k, v in data.items()}
    parent, faces = rng.integers(0, len(F), n), F
    bg = rng.random((cam.height, cam.width, 3))
    weights = rng.normal(size=(cam.height, cam.width, 5))
    cam_a = camera_arrays(cam, dtype)

    @jax.jit
    def world(p):
        return bind(jnp.asarray(parent), p["means"], p["quats"], p["log_scales"], p["opacity_logits"], p["vertices"],
                    jnp.asarray(faces))

    bins = make_bins(*world(params), cam, cam_a, tile=8, chunk=8, near=0.01)
    bits = jnp.asarray(camera_bits(cam, 0.01))

    def loss(p):
        g = world(p)
        if compositor == "fused":
            c, a, d = fused_render(g.means, g.rotmats, g.scales, g.opacities, p["sh"], bits,
                                   jnp.asarray(np.broadcast_to(bg, (cam.height, cam.width, 3)), dtype),
                                   height=cam.height, width=cam.width, count=16)
        else:
            c, a, d = render_bound(g.means, g.rotmats, g.scales, g.opacities, p["sh"], cam_a, jnp.asarray(bg, dtype),
                                   bins.gauss, bins.tile, bins.first, width=cam.width, height=cam.height, tile=8,
                                   sh_degree=3, near=0.01)
        return jnp.sum(jnp.concatenate([c, a[..., None], d[..., None]], -1) * jnp.asarray(weights, dtype))

    return jax.jit(loss), params, dict(data, parent=parent, faces=F, bg=bg, weights=weights)


@pytest.fixture(scope="module", params=COMPOSITORS)
def compositor(request):
    return request.param


@pytest.fixture(scope="module")
def grads64(compositor):
    """float64 gradients and central finite differences (10 random entries per parameter)."""
    rng = np.random.default_rng(0)
    with jax.enable_x64(True):
        loss, params, _ = _grad_problem(jnp.float64, compositor)
        grads = jax.jit(jax.grad(loss))(params)
        eps, fds = 1e-6, {}
        for name, value in params.items():
            flat = np.asarray(value).ravel()
            idx = rng.choice(flat.size, 10, replace=False)
            fd = []
            for i in idx:
                step = np.zeros_like(flat)
                step[i] = eps
                plus = dict(params, **{name: jnp.asarray((flat + step).reshape(value.shape))})
                minus = dict(params, **{name: jnp.asarray((flat - step).reshape(value.shape))})
                fd.append((float(loss(plus)) - float(loss(minus))) / (2 * eps))
            fds[name] = (idx, np.array(fd))
        return {k: np.asarray(v) for k, v in grads.items()}, fds


@pytest.fixture(scope="module")
def grads32(compositor):
    loss, params, data = _grad_problem(jnp.float32, compositor)
    return {k: np.asarray(v, np.float64) for k, v in jax.jit(jax.grad(loss))(params).items()}, data


def test_gradients_match_float64_finite_differences_for_every_parameter(grads64):
    grads, fds = grads64
    for name, (idx, fd) in fds.items():
        g = grads[name].ravel()
        assert np.all(np.isfinite(g)), name
        err = np.abs(g[idx] - fd)
        assert np.all(err <= 1e-3 * np.maximum(np.abs(fd), 1e-2 * np.abs(g).max())), (name, g[idx], fd)


@pytest.mark.agreement
def test_float32_gradients_match_float64_to_1e_3(grads32, grads64):
    for name, b in grads64[0].items():
        a = grads32[0][name]
        assert np.linalg.norm(a - b) <= 1e-3 * np.linalg.norm(b), name
        assert np.all(np.abs(a - b) <= 1e-3 * np.maximum(np.abs(b), 1e-2 * np.abs(b).max())), name


@pytest.mark.agreement
def test_images_and_gradients_match_torch(grads32, compositor):
    """The same loss through the torch backend (binding + rasteriser) gives the same value and gradients."""
    torch = pytest.importorskip("torch")
    from pgc.splats.binding import bind_arrays as torch_bind
    from pgc_torch.splat.rasterizer import rasterize

    g_jax, data = grads32
    names = ("means", "quats", "log_scales", "opacity_logits", "sh", "vertices")
    t = {k: torch.tensor(np.asarray(data[k], np.float32), requires_grad=True) for k in names}
    m, r, s, o = torch_bind(torch.as_tensor(data["parent"]), t["means"], t["quats"], t["log_scales"],
                            t["opacity_logits"], t["vertices"], torch.as_tensor(data["faces"]))
    c, a, d = rasterize(m, r, s, o, t["sh"], GRAD_CAM,
                        torch.as_tensor(data["bg"], dtype=torch.float32), 3, 0.01, 16, "torch", 1)
    loss = (torch.cat([c, a[..., None], d[..., None]], -1) * torch.as_tensor(data["weights"], dtype=torch.float32))
    loss.sum().backward()
    world = np_bind(GaussianSet(data["parent"], data["means"], data["quats"], data["log_scales"],
                                data["opacity_logits"], data["sh"]), data["vertices"], data["faces"])
    out = JaxSplatRenderer({"compositor": compositor}).render(world, GRAD_CAM, data["bg"])
    np.testing.assert_allclose(out.color, c.detach().numpy(), atol=1e-5)
    np.testing.assert_allclose(out.alpha, a.detach().numpy(), atol=1e-5)
    np.testing.assert_allclose(out.depth, d.detach().numpy(), atol=2e-5)
    for name in names:
        gt = t[name].grad.numpy().astype(np.float64)
        assert np.linalg.norm(g_jax[name] - gt) <= 1e-3 * np.linalg.norm(gt), name


def _hard_scene() -> WorldGaussians:
    cases = [
        ([0.0, 0.0, 1.0], [1e-9, 1e-9, 1e-9], [1, 0, 0, 0]),        # tiny scale
        ([0.1, 0.0, 1.2], [1e3, 1e3, 1e3], [1, 0, 0, 0]),          # huge: covers the whole image
        ([0.0, 0.1, 1.5], [1e9, 1e-9, 1.0], [0, 0, 0, 0]),         # clamped needle, zero quaternion
        ([0.0, 0.0, -1.0], [0.1, 0.1, 0.1], [1, 0, 0, 0]),         # behind the camera
        ([0.0, 0.05, 0.0], [0.5, 0.5, 0.5], [1, 0, 0, 0]),         # straddles the near plane (centre behind)
        ([0.05, 0.0, 0.025], [0.3, 0.3, 0.3], [0.3, 0.1, 0, 0]),   # straddles it, centre just in front
        ([0.0, 0.0, 1.0], [0.05, 0.05, 0.05], [1e-30, 0, 0, 0]),   # quaternion of norm 1e-30
    ]
    means, scales, quats = (np.array([c[i] for c in cases], float) for i in range(3))
    n = len(cases)
    sh = np.random.default_rng(0).normal(0, 0.5, (n, 16, 3))
    return WorldGaussians(means, quats, scales, np.linspace(0.3, 0.99, n), sh)


@pytest.mark.parametrize("compositor", COMPOSITORS)
def test_hard_cases_are_finite_and_match_reference(compositor):
    world, cam = _hard_scene(), _camera()
    _assert_matches_reference(world, cam, np.array([0.1, 0.2, 0.3]), {"compositor": compositor})


@pytest.mark.parametrize("compositor", COMPOSITORS)
def test_hard_cases_have_finite_gradients(compositor):
    world, cam = _hard_scene(), _camera()
    arrays = [jnp.asarray(x, jnp.float32) for x in (world.means, world.quats, world.scales, world.opacities, world.sh)]
    ca, bits = camera_arrays(cam), jnp.asarray(camera_bits(cam, 0.01))
    bins = make_bins(arrays[0], jax.jit(quat_to_rotmat)(arrays[1]), *arrays[2:4], cam, ca, tile=16, chunk=32,
                     near=0.01)

    def loss(m, q, s, o, sh):
        if compositor == "fused":
            c, a, d = fused_render(m, quat_to_rotmat(q), s, o, sh, bits, jnp.zeros((H, W, 3)), height=H, width=W,
                                   count=16)
        else:
            c, a, d = render_bound(m, quat_to_rotmat(q), s, o, sh, ca, jnp.zeros(3), bins.gauss, bins.tile,
                                   bins.first, width=W, height=H, tile=16, sh_degree=3, near=0.01)
        return jnp.sum(c) + jnp.sum(a) + jnp.sum(d)

    for g in jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 4)))(*arrays):
        assert np.all(np.isfinite(np.asarray(g)))


@pytest.mark.parametrize("compositor", COMPOSITORS)
def test_empty_set_and_all_culled_give_background(compositor):
    cam, bg = _camera(), np.array([0.25, 0.5, 0.75])
    r = JaxSplatRenderer({"compositor": compositor})
    empty = WorldGaussians(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3)))
    behind = WorldGaussians(np.array([[0.0, 0.0, -2.0]]), np.array([[1.0, 0, 0, 0]]), np.full((1, 3), 0.1),
                            np.ones(1), np.zeros((1, 1, 3)))
    for world in (empty, behind):
        out = r.render(world, cam, bg)
        np.testing.assert_allclose(out.color, np.broadcast_to(bg, (H, W, 3)), atol=1e-7)
        assert np.all(out.alpha == 0) and np.all(out.depth == 0)


def test_registered_and_options_validated():
    from pgc.errors import PGCConfigError
    from pgc.registry import Registry

    impl = Registry.discover().get("splat_renderer", "jax")
    assert impl.available
    with pytest.raises(Exception, match="chunk_size"):
        JaxSplatRenderer({"chunk_size": 2})
    with pytest.raises(PGCConfigError, match="JAX_ENABLE_X64"):
        JaxSplatRenderer({"precision": "float64"})
