"""Mesh binding, quaternions, SH basis and initial Gaussians (pgc.splats) and the torch binding twin."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.splats.binding import K_MIN, bind, triangle_frames, unbind_points
from pgc.splats.init import sample_on_mesh
from pgc.splats.quaternion import quat_multiply, quat_normalize, quat_to_rotmat, rotmat_to_quat
from pgc.splats.sh import SH_C0, rgb_to_sh_dc, sh_basis, sh_to_rgb_dc
from pgc.types import GaussianSet, Mesh

torch = pytest.importorskip("torch")


def _random_gaussians(n: int, faces: int, rng: np.random.Generator, sh_k: int = 16) -> GaussianSet:
    return GaussianSet(parent=rng.integers(0, faces, n), means=rng.normal(size=(n, 3)), quats=rng.normal(size=(n, 4)),
                       log_scales=rng.normal(-1, 0.5, (n, 3)), opacity_logits=rng.normal(size=n),
                       sh=rng.normal(size=(n, sh_k, 3)))


DEGENERATE = {
    "zero_area_collinear": [[0, 0, 0], [1, 0, 0], [2, 0, 0]],
    "repeated_v0_v1": [[0, 0, 0], [0, 0, 0], [0, 1, 0]],
    "repeated_v0_v2": [[0, 0, 0], [1, 1, 0], [0, 0, 0]],
    "point": [[0.3, 0.2, 0.1]] * 3,
    "nearly_collinear": [[0, 0, 0], [1, 0, 0], [0.5, 1e-14, 0]],
}


def test_right_triangle_frame_by_hand():
    v = np.array([[0.0, 0, 0], [2, 0, 0], [0, 1, 0]])
    tau, R, k = triangle_frames(v, np.array([[0, 1, 2]]))
    np.testing.assert_allclose(tau[0], [2 / 3, 1 / 3, 0])
    np.testing.assert_allclose(R[0], [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)  # columns a, n, a x n
    assert k[0] == pytest.approx(1.5)  # (base 2 + height 1) / 2


def test_frames_are_rotations_and_bind_matches_definition():
    rng = np.random.default_rng(0)
    v, f = rng.normal(size=(30, 3)), rng.integers(0, 30, (20, 3))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    tau, R, k = triangle_frames(v, f)
    np.testing.assert_allclose(np.einsum("fji,fjk->fik", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    g = _random_gaussians(50, len(f), rng)
    w = bind(g, v, f)
    p = g.parent
    np.testing.assert_allclose(w.means, k[p, None] * np.einsum("nij,nj->ni", R[p], g.means) + tau[p], atol=1e-12)
    np.testing.assert_allclose(quat_to_rotmat(w.quats), R[p] @ quat_to_rotmat(g.quats), atol=1e-6)
    np.testing.assert_allclose(w.scales, k[p, None] * np.exp(g.log_scales.astype(np.float64)), rtol=1e-12)
    np.testing.assert_allclose(w.opacities, 1 / (1 + np.exp(-g.opacity_logits.astype(np.float64))), rtol=1e-12)
    np.testing.assert_allclose(unbind_points(w.means, p, v, f), g.means, atol=1e-5)


def test_rigid_motion_moves_gaussians_rigidly():
    rng = np.random.default_rng(1)
    v, f = rng.normal(size=(6, 3)), np.array([[0, 1, 2], [3, 4, 5]])
    g = _random_gaussians(10, 2, rng)
    Q = quat_to_rotmat(rng.normal(size=4))
    shift = rng.normal(size=3)
    a, b = bind(g, v, f), bind(g, v @ Q.T + shift, f)
    np.testing.assert_allclose(b.means, a.means @ Q.T + shift, atol=1e-12)
    cov = lambda w: quat_to_rotmat(w.quats) @ (w.scales[:, :, None] ** 2 * np.swapaxes(quat_to_rotmat(w.quats), 1, 2))
    np.testing.assert_allclose(cov(b), Q @ cov(a) @ Q.T, atol=1e-10)


@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_degenerate_triangles_give_finite_documented_frames(name):
    v = np.array(DEGENERATE[name], float)
    tau, R, k = triangle_frames(v, np.array([[0, 1, 2]]))
    assert np.all(np.isfinite(R)) and np.all(np.isfinite(k))
    np.testing.assert_allclose(R[0].T @ R[0], np.eye(3), atol=1e-12)
    assert np.linalg.det(R[0]) == pytest.approx(1.0)
    assert k[0] >= K_MIN
    if name == "point":
        assert k[0] == K_MIN


@pytest.mark.parametrize("name", sorted(DEGENERATE) + ["random"])
def test_torch_binding_matches_numpy_and_has_finite_gradients(name):
    from pgc.splats.binding import bind_arrays as tbind  # the shared maths on torch tensors

    rng = np.random.default_rng(2)
    v = rng.normal(size=(3, 3)) if name == "random" else np.array(DEGENERATE[name], float)
    f = np.array([[0, 1, 2]])
    g = _random_gaussians(8, 1, rng)
    ref = bind(g, v, f)
    vt = torch.tensor(v, requires_grad=True)
    params = [torch.tensor(getattr(g, n), dtype=torch.float64, requires_grad=True)
              for n in ("means", "quats", "log_scales", "opacity_logits")]
    means, rot, scales, opac = tbind(torch.as_tensor(g.parent), *params, vt, torch.as_tensor(f))
    np.testing.assert_allclose(means.detach().numpy(), ref.means, atol=1e-9)
    np.testing.assert_allclose(rot.detach().numpy(), quat_to_rotmat(ref.quats), atol=1e-9)
    np.testing.assert_allclose(scales.detach().numpy(), ref.scales, rtol=1e-9)
    np.testing.assert_allclose(opac.detach().numpy(), ref.opacities, rtol=1e-12)
    (means.sum() + rot.sum() + scales.sum() + opac.sum()).backward()
    for t in [vt, *params]:
        assert torch.isfinite(t.grad).all()


def test_torch_frames_gradcheck_float64():
    from pgc.splats.binding import triangle_frames as tframes

    rng = np.random.default_rng(3)
    v = torch.tensor(rng.normal(size=(5, 3)), requires_grad=True)
    f = torch.tensor([[0, 1, 2], [2, 3, 4], [0, 4, 1]])
    assert torch.autograd.gradcheck(lambda x: tframes(x, f), (v,), eps=1e-7, atol=1e-6)


def test_parent_out_of_range_is_a_clear_error():
    rng = np.random.default_rng(4)
    g = _random_gaussians(3, 5, rng)
    with pytest.raises(PGCDataError, match="parent face index"):
        bind(g, rng.normal(size=(3, 3)), np.array([[0, 1, 2]]))


def test_quaternion_helpers():
    rng = np.random.default_rng(5)
    q = quat_normalize(rng.normal(size=(100, 4)))
    Rq = quat_to_rotmat(q)
    back = rotmat_to_quat(Rq)
    np.testing.assert_allclose(np.abs(np.sum(back * q, axis=1)), 1.0, atol=1e-12)  # same up to sign
    p = quat_normalize(rng.normal(size=(100, 4)))
    np.testing.assert_allclose(quat_to_rotmat(quat_multiply(p, q)), quat_to_rotmat(p) @ Rq, atol=1e-12)
    np.testing.assert_allclose(quat_to_rotmat(np.zeros(4)), np.eye(3))
    # 180-degree rotations (trace -1) are the hard branch of the conversion
    for axis in np.eye(3):
        R = quat_to_rotmat(np.r_[0.0, axis])
        np.testing.assert_allclose(quat_to_rotmat(rotmat_to_quat(R)), R, atol=1e-12)


def test_sh_basis_is_orthonormal_and_dc_roundtrip():
    n = 50000  # Fibonacci sphere quadrature
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)
    B = sh_basis(d, 3)
    gram = 4 * np.pi * B.T @ B / n
    np.testing.assert_allclose(gram, np.eye(16), atol=1e-3)
    assert sh_basis(d[:1], 0)[0, 0] == SH_C0
    c = np.array([0.2, 0.5, 0.9])
    np.testing.assert_allclose(sh_to_rgb_dc(rgb_to_sh_dc(c)), c)


def test_sample_on_mesh_is_uniform_by_area_and_initialised_as_the_paper():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 1], [0, 1, 1]])
    mesh = Mesh(v, np.array([[0, 1, 2], [3, 4, 5]]))  # areas 0.5 and 1.5
    g = sample_on_mesh(mesh, 40000, np.random.default_rng(6))
    assert len(g) == 40000 and g.sh.shape == (40000, 16, 3)
    frac = np.mean(g.parent == 1)
    assert abs(frac - 0.75) < 4 * np.sqrt(0.75 * 0.25 / 40000)
    w = bind(g, mesh.vertices, mesh.faces)
    assert np.all(np.abs(w.means[:, 2] - mesh.vertices[mesh.faces[g.parent, 0], 2]) < 1e-6)  # on the planes
    # inside the triangles: barycentric coordinates in [0, 1]
    tri = mesh.vertices[mesh.faces[g.parent]]
    e1, e2, p = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], w.means - tri[:, 0]
    a = np.linalg.solve(np.stack([e1[:, :2], e2[:, :2]], -1), p[:, :2, None])[..., 0]
    assert a.min() > -1e-6 and a.sum(1).max() < 1 + 1e-6
    np.testing.assert_allclose(g.quats, np.tile([1, 0, 0, 0], (40000, 1)))
    np.testing.assert_allclose(g.log_scales, 0)
    np.testing.assert_allclose(w.opacities, 0.1, rtol=1e-6)
    dc = sh_to_rgb_dc(g.sh[:, 0])
    assert dc.min() >= 0.5 - 1e-6 and dc.max() <= 0.7 + 1e-6 and np.all(g.sh[:, 1:] == 0)


def test_sample_on_mesh_rejects_meshes_without_area():
    mesh = Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]]), name="flat")
    with pytest.raises(PGCDataError, match="flat"):
        sample_on_mesh(mesh, 10, np.random.default_rng(0))
