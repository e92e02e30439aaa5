"""Conformance suites: the role contracts (``pgc/roles``) as pytest test classes.

A plugin author subclasses the suite of their role in a test module (its name must start with ``Test``)
and overrides the ``implementation`` fixture to return an instance of their implementation::

    from pgc.testing.conformance import FilterConformance

    class TestBoxBlur(FilterConformance):
        @pytest.fixture
        def implementation(self):
            return BoxBlurFilter()

Every check is small (images of a few hundred pixels, meshes of a few dozen vertices) so a suite runs
in seconds. The built-in implementations run the same suites (``tests/test_conformance.py``; the body models'
in ``tests/test_body_model.py``, beside their own tests).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.motion.rotations import axis_angle_to_matrix


class _Suite:
    @pytest.fixture
    def implementation(self) -> Any:
        pytest.fail(f"{type(self).__name__}: override the 'implementation' fixture to return the object under test")


# ----------------------------------------------------------------------------------------------- filter


class FilterConformance(_Suite):
    """Contract of ``pgc.roles.filter.Filter``: alpha-aware low-pass, high + low = identity."""

    KERNELS = (1, 5, 31)
    """Kernel sizes tried; 31 is wider than the 13 x 17 test image."""

    @pytest.fixture
    def scene(self) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(7)
        image = rng.random((13, 17, 3)).astype(np.float32)
        alpha = rng.random((13, 17)).astype(np.float32)
        alpha[rng.random((13, 17)) < 0.3] = 0.0
        return image, alpha

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_shape_and_dtype(self, implementation, scene, kernel):
        image, alpha = scene
        out = implementation.lowpass(image, alpha, kernel)
        assert out.shape == image.shape and out.dtype == np.float32
        assert np.all(np.isfinite(out))

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_alpha_zero_gives_the_image(self, implementation, scene, kernel):
        image, _ = scene
        out = implementation.lowpass(image, np.zeros(image.shape[:2], np.float32), kernel)
        np.testing.assert_allclose(out, image, atol=1e-6)

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_tiny_alpha_is_finite(self, implementation, scene, kernel):
        image, _ = scene
        out = implementation.lowpass(image, np.full(image.shape[:2], 1e-30, np.float32), kernel)
        assert np.all(np.isfinite(out))

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_high_plus_low_is_identity(self, implementation, scene, kernel):
        image, alpha = scene
        low = implementation.lowpass(image, alpha, kernel)
        high = implementation.highpass(image, alpha, kernel)
        np.testing.assert_allclose(high + low, image, atol=1e-6)

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_constant_image_unchanged(self, implementation, scene, kernel):
        _, alpha = scene
        image = np.broadcast_to(np.array([0.2, 0.5, 0.9], np.float32), (13, 17, 3)).copy()
        np.testing.assert_allclose(implementation.lowpass(image, alpha, kernel), image, atol=1e-5)

    @pytest.mark.parametrize("kernel", KERNELS)
    def test_background_does_not_bleed(self, implementation, kernel):
        alpha = np.zeros((13, 17), np.float32)
        alpha[3:10, 4:12] = 1.0
        image = np.full((13, 17, 3), 100.0, np.float32)
        image[alpha > 0] = [0.3, 0.6, 0.1]
        out = implementation.lowpass(image, alpha, kernel)
        np.testing.assert_allclose(out[alpha > 0], np.broadcast_to([0.3, 0.6, 0.1], (56, 3)), atol=1e-5)


# ----------------------------------------------------------------------------------------------- metric


class MetricConformance(_Suite):
    """Contract of ``pgc.roles.metric.Metric``: identical images score best, shape mismatches raise."""

    @pytest.fixture
    def images(self) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(3)
        yy, xx = np.mgrid[0:48, 0:48] / 48.0
        target = np.stack([0.5 + 0.3 * np.sin(6 * xx), 0.4 + 0.3 * np.cos(5 * yy), 0.3 + 0.2 * xx * yy], -1)
        noisy = np.clip(target + rng.normal(0, 0.05, target.shape), 0, 1)
        return target.astype(np.float32), noisy.astype(np.float32)

    def _better_or_equal(self, impl, a: float, b: float) -> bool:
        return a >= b if impl.higher_is_better else a <= b

    def test_identical_images_score_best(self, implementation, images):
        target, noisy = images
        same = implementation(target, target)
        worse = implementation(noisy, target)
        assert not np.isnan(same) and np.isfinite(worse)
        assert self._better_or_equal(implementation, same, worse) and same != worse

    def test_more_distortion_scores_worse(self, implementation, images):
        target, noisy = images
        very = np.clip(target + 4 * (noisy - target), 0, 1)
        assert self._better_or_equal(implementation, implementation(noisy, target), implementation(very, target))

    def test_masked_identical_scores_best(self, implementation, images):
        target, noisy = images
        mask = np.zeros(target.shape[:2], np.float32)
        mask[8:40, 10:36] = 1.0
        same, worse = implementation(target, target, mask), implementation(noisy, target, mask)
        assert not np.isnan(same) and np.isfinite(worse)
        assert self._better_or_equal(implementation, same, worse)

    def test_shape_mismatch_raises(self, implementation, images):
        target, _ = images
        with pytest.raises(PGCDataError):
            implementation(target[:-1], target)
        with pytest.raises(PGCDataError):
            implementation(target, target, np.ones((3, 3), np.float32))


# ------------------------------------------------------------------------------------------------- brdf


def _hemisphere_grid(n_theta: int = 48, n_phi: int = 96) -> tuple[np.ndarray, float]:
    """Midpoint directions uniform in (cos theta, phi) on the upper hemisphere and the solid angle of each."""
    u = (np.arange(n_theta) + 0.5) / n_theta
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    u, phi = np.meshgrid(u, phi, indexing="ij")
    s = np.sqrt(1 - u * u)
    dirs = np.stack([s * np.cos(phi), s * np.sin(phi), u], -1).reshape(-1, 3)
    return dirs, 2 * np.pi / (n_theta * n_phi)


def _direction(cos_theta: float, phi: float = 0.3) -> np.ndarray:
    s = np.sqrt(max(0.0, 1 - cos_theta ** 2))
    return np.array([s * np.cos(phi), s * np.sin(phi), cos_theta])


class BRDFConformance(_Suite):
    """Contract of ``pgc.roles.brdf.BRDF`` on the numpy backend: finite everywhere, zero below the surface,
    non-negative, and a white furnace (base colour 1) reflects at most what it receives."""

    FURNACE_TOLERANCE = 0.02
    """Allowed excess over the limit from the 48 x 96 quadrature of the hemisphere."""

    def furnace_limit(self, implementation) -> float:
        """1, unless the implementation declares ``furnace_limit`` (a published model that is not energy
        conserving by design states its bound there, and the suite holds it to that)."""
        return float(getattr(implementation, "furnace_limit", 1.0))

    def _params(self, impl, where: str = "init") -> dict[str, np.ndarray]:
        out = {}
        for p in impl.parameters:
            value = {"init": p.init, "lower": (p.lower,) * p.size, "upper": (p.upper,) * p.size}[where]
            out[p.name] = np.asarray(value[0] if p.size == 1 else value, dtype=np.float64)
        return out

    @pytest.mark.parametrize("where", ["init", "lower", "upper"])
    def test_finite_at_grazing_angles(self, implementation, where):
        cosines = [1.0, 0.5, 1e-3, 1e-8, 0.0]
        wi = np.stack([_direction(c, 0.1) for c in cosines for _ in cosines])
        wo = np.stack([_direction(c, 2.0) for _ in cosines for c in cosines])
        out = np.asarray(implementation.eval_cos(wi, wo, np.ones((len(wi), 3)), self._params(implementation, where)))
        assert out.shape == (len(wi), 3)
        assert np.all(np.isfinite(out)) and np.all(out >= 0)

    def test_normal_parallel_to_view(self, implementation):
        wo = np.array([[0.0, 0.0, 1.0]])
        out = np.asarray(implementation.eval_cos(wo, wo, np.ones((1, 3)), self._params(implementation)))
        assert np.all(np.isfinite(out)) and np.all(out >= 0)

    def test_zero_below_the_surface(self, implementation):
        up, down = _direction(0.6), _direction(-0.4)
        wi = np.stack([down, up, down])
        wo = np.stack([up, down, down])
        out = np.asarray(implementation.eval_cos(wi, wo, np.ones((3, 3)), self._params(implementation)))
        np.testing.assert_array_equal(out, 0.0)

    @pytest.mark.parametrize("where", ["init", "lower", "upper"])
    @pytest.mark.parametrize("cos_o", [1.0, 0.5, 0.05])
    def test_white_furnace(self, implementation, where, cos_o):
        wi, d_omega = _hemisphere_grid()
        wo = np.broadcast_to(_direction(cos_o, 1.0), wi.shape)
        value = np.asarray(implementation.eval_cos(wi, wo, np.ones(wi.shape), self._params(implementation, where)))
        albedo = value.sum(axis=0) * d_omega
        assert np.all(np.isfinite(albedo))
        limit = self.furnace_limit(implementation)
        assert np.all(albedo <= limit + self.FURNACE_TOLERANCE), \
            f"reflects {albedo} > {limit} of the light at cos_o={cos_o} with parameters at {where}"


# -------------------------------------------------------------------------------------------- simulator


class SimulatorConformance(_Suite):
    """Contract of ``pgc.roles.simulator.Simulator``: (T, V, 3) finite float32 output for a small scene."""

    @pytest.fixture
    def scene(self):
        from pgc.types import BodyMotion, Mesh

        n = 5  # a 20 cm square of cloth, 25 vertices, 10 cm above a static box-shaped body
        u, v = np.meshgrid(np.linspace(-0.1, 0.1, n), np.linspace(-0.1, 0.1, n), indexing="ij")
        verts = np.stack([u.ravel(), np.full(n * n, 1.0), v.ravel()], 1)
        idx = np.arange(n * n).reshape(n, n)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        faces = np.concatenate([np.stack([a, d, c], 1), np.stack([a, c, b], 1)])
        garment = Mesh(verts, faces, name="patch")
        corners = np.array([[x, y, z] for x in (-0.15, 0.15) for y in (0.6, 0.9) for z in (-0.15, 0.15)])
        box_faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                              [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
        motion = BodyMotion(np.repeat(corners[None], 4, axis=0), box_faces, fps=30.0, name="static")
        return garment, motion

    def test_output_shape_and_finite(self, implementation, scene):
        garment, motion = scene
        sim = implementation.simulate(garment, motion)
        vertices = np.asarray(sim.vertices)
        assert vertices.shape == (motion.num_frames, len(garment.vertices), 3)
        assert vertices.dtype == np.float32
        assert np.all(np.isfinite(vertices))
        assert isinstance(sim.figures, dict)


# ------------------------------------------------------------------------------------------- body_model


def _random_rotations(rng: np.random.Generator, joints: int, scale: float = 0.5) -> np.ndarray:
    """(joints, 3, 3) rotations about random axes, angles ~ N(0, scale) radians per component."""
    return axis_angle_to_matrix(rng.normal(0, scale, (joints, 3)))


class BodyModelConformance(_Suite):
    """Contract of ``pgc.roles.body_model.BodyModel``: rig, rest placement, skinning, gradients, bad input."""

    def test_rig_and_rest_placement(self, implementation):
        rig = implementation.rig()
        J = len(rig.names)
        assert rig.parents.shape == (J,) and rig.parents[0] == -1
        assert np.all(rig.parents[1:] < np.arange(1, J)) and np.all(rig.parents[1:] >= 0)
        assert rig.joints.shape == (J, 3) and np.all(np.isfinite(rig.joints))
        rest = implementation.forward()
        assert rest.vertices.dtype == np.float64 and rest.faces.dtype == np.int64
        assert rest.faces.min() >= 0 and rest.faces.max() < len(rest.vertices)
        assert rest.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-9)
        assert np.abs(rest.joints[0, [0, 2]]).max() < 1e-9
        np.testing.assert_allclose(rest.transforms, np.broadcast_to(np.eye(4), (J, 4, 4)), atol=1e-12)
        assert implementation.weights.shape == (len(rest.vertices), J) and implementation.weights.min() > -1e-9  # Anny: -8e-11
        np.testing.assert_allclose(implementation.weights.sum(axis=1), 1.0, atol=1e-6)

    def test_rigid_skinning_follows_the_weights(self, implementation):
        """Without pose-corrective shapes, a posed vertex is the weighted blend of its joints' transforms."""
        rng = np.random.default_rng(7)
        rest = implementation.forward()
        state = implementation.forward(None, _random_rotations(rng, len(implementation.joint_names), 0.3))
        blended = np.einsum("vj,jab->vab", implementation.weights, state.transforms)
        expected = np.einsum("vab,vb->va", blended[:, :3, :3], rest.vertices) + blended[:, :3, 3]
        corrective = 0.01 if "beta0" in implementation.parameters else 1e-9  # SMPL adds pose blend shapes (tiny file: mm)
        assert np.abs(state.vertices - expected).max() < corrective

    def test_faces_point_outward(self, implementation):
        rest = implementation.forward()
        v, f = rest.vertices, rest.faces
        assert np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() > 0

    def test_translation_moves_everything_rigidly(self, implementation):
        rng = np.random.default_rng(0)
        rotations = _random_rotations(rng, len(implementation.joint_names))
        a = implementation.forward(None, rotations)
        b = implementation.forward(None, rotations, np.array([0.1, -0.2, 0.3]))
        np.testing.assert_allclose(b.vertices - a.vertices, np.broadcast_to([0.1, -0.2, 0.3], a.vertices.shape),
                                   atol=1e-9)
        np.testing.assert_allclose(b.joints - a.joints, np.broadcast_to([0.1, -0.2, 0.3], a.joints.shape),
                                   atol=1e-9)

    def test_root_rotation_turns_the_skeleton_about_the_root(self, implementation):
        rest = implementation.forward()
        rotations = np.broadcast_to(np.eye(3), (len(implementation.joint_names), 3, 3)).copy()
        rotations[0] = axis_angle_to_matrix(np.array([0.0, np.pi / 2, 0.0]))
        turned = implementation.forward(None, rotations)
        expected = (rest.joints - rest.joints[0]) @ rotations[0].T + rest.joints[0]
        np.testing.assert_allclose(turned.joints, expected, atol=1e-9)

    def test_posed_joints_follow_the_transforms(self, implementation):
        rng = np.random.default_rng(1)
        rig = implementation.rig()
        state = implementation.forward(None, _random_rotations(rng, len(rig.names)), rng.normal(0, 0.2, 3))
        mapped = np.einsum("jab,jb->ja", state.transforms[:, :3, :3], rig.joints) + state.transforms[:, :3, 3]
        np.testing.assert_allclose(state.joints, mapped, atol=1e-9)
        # bone lengths are kept
        bones = rig.parents[1:]
        np.testing.assert_allclose(np.linalg.norm(state.joints[1:] - state.joints[bones], axis=1),
                                   np.linalg.norm(rig.joints[1:] - rig.joints[bones], axis=1), atol=1e-9)

    def test_skin_identity_clip_is_the_rest_mesh_and_frames_match_forward(self, implementation):
        J = len(implementation.joint_names)
        rest = implementation.forward().vertices
        clip = implementation.skin(None, np.broadcast_to(np.eye(3), (3, J, 3, 3)))
        assert clip.dtype == np.float32 and clip.shape == (3,) + rest.shape
        np.testing.assert_allclose(clip, np.broadcast_to(rest, clip.shape), atol=1e-6)
        rng = np.random.default_rng(2)
        rotations = np.stack([_random_rotations(rng, J) for _ in range(3)])
        clip = implementation.skin(None, rotations, chunk=2)
        np.testing.assert_allclose(clip[2], implementation.forward(None, rotations[2]).vertices, atol=1e-5)

    def test_torch_float64_gradients_match_finite_differences(self, implementation):
        import torch

        rng = np.random.default_rng(4)
        names = list(implementation.parameters)[:2]
        start = implementation.check_shape({n: implementation.parameters[n].low + (0.37 + 0.21 * i) * (implementation.parameters[n].high
                                                                                    - implementation.parameters[n].low)
                                  for i, n in enumerate(names)})  # away from Anny's interpolation anchors
        rotations = torch.tensor(_random_rotations(rng, len(implementation.joint_names), 0.3)[None])
        translation = torch.tensor([[0.1, 0.2, 0.3]], dtype=torch.float64, requires_grad=True)
        weights = torch.tensor(rng.normal(size=implementation.forward().vertices.shape)[None])

        def f(x):
            shape = {n: torch.tensor([v], dtype=torch.float64) for n, v in start.items()}
            shape.update({n: x[i:i + 1] for i, n in enumerate(names)})
            return (implementation.forward_torch(shape, rotations, translation).vertices * weights).sum()

        x = torch.tensor([start[n] for n in names], dtype=torch.float64, requires_grad=True)
        value = f(x)
        assert value.dtype == torch.float64
        value.backward()
        assert torch.isfinite(x.grad).all() and x.grad.abs().max() > 0
        np.testing.assert_allclose(translation.grad.numpy()[0], weights.sum(dim=(0, 1)).numpy(), rtol=1e-12)
        h = 1e-6
        with torch.no_grad():
            numeric = [(f(x + h * e) - f(x - h * e)).item() / (2 * h) for e in torch.eye(len(names), dtype=x.dtype)]
        np.testing.assert_allclose(x.grad.numpy(), numeric, rtol=1e-6, atol=1e-8)

    def test_bad_inputs_get_one_clear_error(self, implementation):
        J = len(implementation.joint_names)
        name, spec = next(iter(implementation.parameters.items()))
        with pytest.raises(PGCDataError, match="unknown shape parameter.*'shoe_size'"):
            implementation.forward({"shoe_size": 1.0})
        with pytest.raises(PGCDataError, match=f"'{name}' = {spec.high + 1} is outside its range"):
            implementation.forward({name: spec.high + 1})
        with pytest.raises(PGCDataError, match="finite number"):
            implementation.forward({name: True})
        with pytest.raises(PGCDataError, match="NaN"):
            implementation.forward(None, np.full((J, 3, 3), np.nan))
        with pytest.raises(PGCDataError, match="T >= 1"):
            implementation.skin(None, np.zeros((0, J, 3, 3)))


# --------------------------------------------------------------------------------------- splat_renderer


class SplatRendererConformance(_Suite):
    """Contract of ``pgc.roles.splat_renderer.SplatRenderer.render`` on tiny images."""

    @pytest.fixture
    def camera(self):
        from pgc.types import Camera

        K = np.array([[20.0, 0, 8.0], [0, 20.0, 6.0], [0, 0, 1]])
        return Camera(K=K, R=np.eye(3), t=np.zeros(3), width=16, height=12, name="c")

    def _gaussians(self, means: np.ndarray, opacity: float = 0.9):
        from pgc.types import WorldGaussians

        n = len(means)
        return WorldGaussians(means=np.asarray(means, float).reshape(n, 3), quats=np.tile([1.0, 0, 0, 0], (n, 1)),
                              scales=np.full((n, 3), 0.05), opacities=np.full(n, opacity),
                              sh=np.full((n, 1, 3), 0.5))

    def test_empty_set_renders_background(self, implementation, camera):
        background = np.random.default_rng(0).random((12, 16, 3)).astype(np.float32)
        out = implementation.render(self._gaussians(np.zeros((0, 3))), camera, background=background)
        np.testing.assert_allclose(out.color, background, atol=1e-6)
        np.testing.assert_allclose(out.alpha, 0.0, atol=1e-7)
        out = implementation.render(self._gaussians(np.zeros((0, 3))), camera, background=np.array([0.1, 0.2, 0.3]))
        np.testing.assert_allclose(out.color, np.broadcast_to([0.1, 0.2, 0.3], (12, 16, 3)), atol=1e-6)

    def test_gaussian_behind_camera_is_invisible(self, implementation, camera):
        out = implementation.render(self._gaussians([[0.0, 0.0, -1.0]]), camera, background=np.zeros(3))
        np.testing.assert_allclose(out.alpha, 0.0, atol=1e-7)
        assert np.all(np.isfinite(out.color))

    def test_gaussian_in_front_is_visible_and_finite(self, implementation, camera):
        out = implementation.render(self._gaussians([[0.0, 0.0, 1.0]]), camera, background=np.zeros(3))
        assert out.color.shape == (12, 16, 3) and out.alpha.shape == (12, 16)
        assert np.all(np.isfinite(out.color)) and np.all(np.isfinite(out.alpha))
        assert 0.5 < out.alpha[6, 8] <= 0.99 + 1e-6
        assert out.alpha.min() >= 0.0 and out.alpha.max() <= 1.0
        if out.depth is not None:
            assert np.all(np.isfinite(out.depth))
            np.testing.assert_allclose(out.depth[6, 8], 1.0, rtol=1e-3)


# ------------------------------------------------------------------------------------- albedo_estimator


class AlbedoEstimatorConformance(_Suite):
    """Contract of ``pgc.roles.albedo_estimator.AlbedoEstimator``: (H, W, 3) float32 albedo in [0, 1],
    finite everywhere (black images, zero shading), ``shading`` demanded only by those that declare it."""

    @pytest.fixture
    def scene(self) -> dict[str, np.ndarray]:
        yy, xx = np.mgrid[0:40, 0:48] / 40.0
        albedo = np.stack([0.6 + 0.2 * np.sin(8 * xx), 0.4 + 0.1 * np.cos(7 * yy), np.full_like(xx, 0.3)], -1)
        shading = np.repeat((0.3 + 0.7 * xx / xx.max())[..., None], 3, axis=2)
        mask = np.zeros((40, 48))
        mask[5:35, 6:42] = 1.0
        return {"image": (albedo * shading).astype(np.float32), "shading": shading.astype(np.float32),
                "mask": mask.astype(np.float32)}

    def _estimate(self, impl, image, mask, shading):
        return np.asarray(impl.estimate(image, mask, shading if getattr(impl, "needs_shading", False) else None))

    def test_shape_dtype_range(self, implementation, scene):
        out = self._estimate(implementation, scene["image"], scene["mask"], scene["shading"])
        assert out.shape == (40, 48, 3) and out.dtype == np.float32
        assert np.all(np.isfinite(out))
        inside = out[scene["mask"] > 0]
        assert inside.min() >= 0.0 and inside.max() <= 1.0

    def test_black_image_and_zero_shading_are_finite(self, implementation, scene):
        black = np.zeros_like(scene["image"])
        out = self._estimate(implementation, black, None, np.zeros_like(scene["shading"]))
        assert out.shape == black.shape and np.all(np.isfinite(out))

    def test_missing_shading_raises_when_needed(self, implementation, scene):
        if not getattr(implementation, "needs_shading", False):
            out = np.asarray(implementation.estimate(scene["image"], scene["mask"]))
            assert np.all(np.isfinite(out))
            return
        with pytest.raises(PGCDataError):
            implementation.estimate(scene["image"], scene["mask"])


# ----------------------------------------------------------------------------------------- pbr_renderer


def uv_sphere(radius: float = 0.3, n_lat: int = 12, n_lon: int = 24):
    """A closed UV sphere (``pgc.types.Mesh``, counter-clockwise from outside) with a lat-long UV atlas whose
    seam at longitude 0 splits texture vertices (not positions)."""
    from pgc.types import Mesh

    theta = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, n_lon + 1)[:-1]
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    vertices = radius * np.concatenate([[[0, 1, 0]], ring, [[0, -1, 0]]])
    south = len(vertices) - 1

    def v(i, j):  # ring i, longitude j
        return 1 + i * n_lon + j % n_lon

    def tv(i, j):  # texture vertex of ring i (0..n_lat), longitude j (0..n_lon)
        return i * (n_lon + 1) + j

    uv = np.array([[j / n_lon, 1 - i / n_lat] for i in range(n_lat + 1) for j in range(n_lon + 1)])
    faces, face_uv = [], []
    for j in range(n_lon):
        faces.append([0, v(0, j), v(0, j + 1)])
        face_uv.append([tv(0, j), tv(1, j), tv(1, j + 1)])
        faces.append([south, v(n_lat - 2, j + 1), v(n_lat - 2, j)])
        face_uv.append([tv(n_lat, j), tv(n_lat - 1, j + 1), tv(n_lat - 1, j)])
        for i in range(n_lat - 2):
            faces += [[v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)]]
            face_uv += [[tv(i + 1, j), tv(i + 2, j), tv(i + 2, j + 1)], [tv(i + 1, j), tv(i + 2, j + 1), tv(i + 1, j + 1)]]
    return Mesh(vertices, np.array(faces), uv, np.array(face_uv), name="sphere")


class PBRRendererConformance(_Suite):
    """Contract of ``pgc.roles.pbr_renderer.PBRRenderer`` on a white-furnace-like scene: a convex Lambertian
    sphere of albedo 0.5 under a constant environment of radiance L (no shadowing, no inter-reflection)
    reflects exactly ``0.5 L`` toward every viewer, in screen space and at the texels that face the camera
    (the contract leaves texels that face away unspecified)."""

    ALBEDO = 0.5
    RADIANCE = (1.0, 0.8, 0.6)
    TOLERANCE = 0.05
    """Relative error allowed on the mean radiance (sampling noise, direction sets, silhouette pixels)."""

    @pytest.fixture
    def scene(self):
        from pgc.types import Camera, Light, Material

        material = Material("lambertian", {}, np.full((16, 32, 3), self.ALBEDO, np.float32))
        camera = Camera(K=np.array([[40.0, 0, 12], [0, 40.0, 12], [0, 0, 1]]), R=np.eye(3),
                        t=np.array([0.0, 0.0, 1.5]), width=24, height=24, name="front")
        return uv_sphere(), material, Light(radiance=np.array(self.RADIANCE)), camera

    def test_screen_space_furnace(self, implementation, scene):
        mesh, material, light, camera = scene
        out = implementation.render(mesh, material, light, camera)
        assert out.color.shape == (24, 24, 3) and out.alpha.shape == (24, 24)
        assert np.all(np.isfinite(out.color)) and np.all(np.isfinite(out.alpha))
        assert out.alpha.min() >= 0.0 and out.alpha.max() <= 1.0 + 1e-6
        assert out.alpha[0, 0] == 0.0 and np.all(out.color[0, 0] == 0.0)  # black background, no coverage
        inner = out.alpha > 0.999
        assert inner.sum() > 50
        expected = self.ALBEDO * np.array(self.RADIANCE)
        np.testing.assert_allclose(out.color[inner].mean(axis=0), expected, rtol=self.TOLERANCE)

    def test_camera_looking_away_sees_nothing(self, implementation, scene):
        from dataclasses import replace

        mesh, material, light, camera = scene
        away = replace(camera, R=np.diag([-1.0, 1.0, -1.0]), t=np.array([0.0, 0.0, -1.5]))  # at z = -1.5, facing -z
        out = implementation.render(mesh, material, light, away)
        np.testing.assert_array_equal(out.alpha, 0.0)
        np.testing.assert_array_equal(out.color, 0.0)

    def test_texture_space_furnace(self, implementation, scene):
        mesh, material, light, camera = scene
        radiance, coverage = implementation.render_texture(mesh, material, light, camera, (16, 32))
        radiance, coverage = np.asarray(radiance), np.asarray(coverage)
        assert radiance.shape == (16, 32, 3) and coverage.shape == (16, 32)
        assert np.all(np.isfinite(radiance)) and coverage.min() >= 0.0 and coverage.max() <= 1.0 + 1e-6
        # texel centres on the sphere (the atlas is lat-long: u = longitude / 2 pi, v = 1 - latitude / pi)
        u = (np.arange(32) + 0.5) / 32
        v = 1 - (np.arange(16) + 0.5) / 16
        theta, phi = np.meshgrid((1 - v) * np.pi, 2 * np.pi * u, indexing="ij")
        normal = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)], -1)
        to_camera = camera.center - 0.3 * normal
        facing = np.sum(normal * to_camera, -1) / np.linalg.norm(to_camera, axis=-1)
        front = (coverage > 0.999) & (facing > 0.3)
        assert front.sum() > 50
        expected = self.ALBEDO * np.array(self.RADIANCE)
        np.testing.assert_allclose(radiance[front].mean(axis=0), expected, rtol=self.TOLERANCE)


# ---------------------------------------------------------------------------------------- reconstructor


class ReconstructorConformance(_Suite):
    """Contract of ``pgc.roles.reconstructor.Reconstructor`` on bad input: a capture whose masks are empty,
    or with a single view, fails with :class:`PGCDataError` (before any expensive work)."""

    def _capture(self, n_views: int, empty_masks: bool):
        from pgc.types import Camera, Capture, View

        views = []
        for i in range(n_views):
            a = 2 * np.pi * i / max(n_views, 1)
            c, s = np.cos(a), np.sin(a)
            R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # looking at the origin from radius 2
            cam = Camera(K=np.array([[30.0, 0, 16], [0, 30.0, 16], [0, 0, 1]]), R=R, t=np.array([0, 0, 2.0]),
                         width=32, height=32, name=f"v{i}")
            mask = np.zeros((32, 32), np.float32)
            if not empty_masks:
                mask[10:22, 12:20] = 1.0
            views.append(View(cam, np.full((32, 32, 3), 0.5, np.float32), mask=mask,
                              segmentation=(2 * mask).astype(np.uint8)))
        return Capture(views)

    def test_empty_masks_raise(self, implementation):
        with pytest.raises(PGCDataError):
            implementation.reconstruct(self._capture(6, empty_masks=True))

    def test_single_view_raises(self, implementation):
        with pytest.raises(PGCDataError):
            implementation.reconstruct(self._capture(1, empty_masks=False))


# --------------------------------------------------------------------------------------- scene_renderer


class SceneRendererConformance(_Suite):
    """Contract of ``pgc.roles.scene_renderer.SceneRenderer`` on one Lambertian triangle parallel to the image
    plane at depth 2 m under a constant environment: the mask is the fraction of sub-pixel centres inside the
    projected triangle, the depth is 2 m, the segmentation is the garment where most samples hit it, the
    albedo is the base colour, and a fully covered pixel's colour is ``albedo * L`` (nothing occludes the
    environment, so every path's expected value is that)."""

    ALBEDO = 0.5
    RADIANCE = (1.0, 0.8, 0.6)
    DEPTH = 2.0
    CORNERS = ((4.3, 4.1), (20.2, 6.7), (8.9, 19.6))
    """Pixel positions of the triangle's corners (no sub-pixel centre lies on an edge)."""
    SAMPLES = 4
    TOLERANCE = 0.03
    """Relative error allowed on the mean colour of the fully covered pixels (16 spp, sampling noise)."""

    @pytest.fixture
    def camera(self):
        from pgc.types import Camera

        return Camera(K=np.array([[40.0, 0, 12], [0, 40.0, 12], [0, 0, 1]]), R=np.eye(3), t=np.zeros(3),
                      width=24, height=24, name="front")

    @pytest.fixture
    def geometry(self, camera):
        from pgc.roles.scene_renderer import SceneGeometry
        from pgc.types import Material, Mesh

        pix = np.array([[u, v, 1.0] for u, v in self.CORNERS])
        vertices = self.DEPTH * pix @ np.linalg.inv(camera.K).T
        triangle = Mesh(vertices, np.array([[0, 2, 1]]), name="garment")
        return SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), triangle,
                             Material("lambertian", {"base_color": [self.ALBEDO] * 3}))

    def _expected_mask(self, camera) -> np.ndarray:
        s = self.SAMPLES
        off = (np.arange(s) + 0.5) / s
        ys, xs = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64)
        oy, ox = np.meshgrid(off, off, indexing="ij")
        px, py = xs[..., None] + ox.reshape(-1), ys[..., None] + oy.reshape(-1)
        (x0, y0), (x1, y1), (x2, y2) = self.CORNERS
        inside = np.ones(px.shape, bool)
        for (ax, ay), (bx, by) in (((x0, y0), (x1, y1)), ((x1, y1), (x2, y2)), ((x2, y2), (x0, y0))):
            inside &= (bx - ax) * (py - ay) - (by - ay) * (px - ax) > 0
        return inside.mean(axis=2)

    def test_ground_truth_layers_are_exact(self, implementation, camera, geometry):
        from pgc.types import GARMENT_LABEL, Light

        scene, labels = implementation.build_scene(geometry, Light(radiance=np.array(self.RADIANCE)))
        layers = implementation.ground_truth_layers(scene, labels, geometry, camera, self.SAMPLES)
        expected = self._expected_mask(camera)
        assert expected.max() == 1.0 and expected[expected > 0].min() < 1.0  # inner and edge pixels exist
        for key in ("mask", "depth", "garment_coverage"):
            assert layers[key].shape == (24, 24) and layers[key].dtype == np.float32
            assert np.all(np.isfinite(layers[key]))
        assert layers["albedo"].shape == (24, 24, 3) and layers["segmentation"].dtype == np.uint8
        # a float32 ray may land on the other side of an edge only within rounding: one sample at most
        assert np.abs(layers["mask"] - expected).max() <= 1.0 / self.SAMPLES ** 2 + 1e-6
        assert np.abs(layers["mask"] - expected).mean() < 2e-3
        np.testing.assert_array_equal(layers["garment_coverage"], layers["mask"])
        covered = layers["mask"] > 0
        np.testing.assert_allclose(layers["depth"][covered], self.DEPTH, rtol=1e-5)
        np.testing.assert_array_equal(layers["depth"][~covered], 0.0)
        np.testing.assert_allclose(layers["albedo"][covered], self.ALBEDO, rtol=1e-6)
        np.testing.assert_array_equal(layers["albedo"][~covered], 0.0)
        np.testing.assert_array_equal(layers["segmentation"][expected > 0.55], GARMENT_LABEL)
        np.testing.assert_array_equal(layers["segmentation"][expected < 0.45], 0)

    def test_color_is_albedo_times_radiance(self, implementation, camera, geometry):
        from pgc.types import Light

        scene, _ = implementation.build_scene(geometry, Light(radiance=np.array(self.RADIANCE)))
        color, alpha = implementation.render_color(scene, camera, 16, 3)
        assert color.shape == (24, 24, 3) and alpha.shape == (24, 24)
        assert np.all(np.isfinite(color)) and alpha.min() >= 0.0 and alpha.max() <= 1.0 + 1e-6
        expected = np.pad(self._expected_mask(camera), 1, mode="edge")
        near = np.stack([expected[1 + dy:25 + dy, 1 + dx:25 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
        inner, outside = near.min(0) == 1.0, near.max(0) == 0.0  # away from the edges by a pixel
        assert inner.sum() > 40 and outside.sum() > 300
        np.testing.assert_allclose(alpha, 1.0, atol=1e-6)  # every ray ends on the triangle or the environment
        np.testing.assert_allclose(color[inner].mean(axis=0), self.ALBEDO * np.array(self.RADIANCE),
                                   rtol=self.TOLERANCE)
        np.testing.assert_allclose(color[outside], np.broadcast_to(self.RADIANCE, (outside.sum(), 3)), rtol=1e-5)
        again, _ = implementation.render_color(scene, camera, 16, 3)
        np.testing.assert_array_equal(again, color)

    def test_empty_scene_sees_the_light(self, implementation, camera):
        from pgc.types import Light

        scene, _ = implementation.build_scene(None, Light(radiance=np.array(self.RADIANCE)))
        layers = implementation.ground_truth_layers(scene, {}, None, camera, 2)
        for key, value in layers.items():
            assert value.shape[:2] == (24, 24), key
            np.testing.assert_array_equal(value, 0)
        color, alpha = implementation.render_color(scene, camera, 4, 0)
        np.testing.assert_allclose(alpha, 1.0, atol=1e-6)
        np.testing.assert_allclose(color, np.broadcast_to(self.RADIANCE, (24, 24, 3)), rtol=1e-5)


# ------------------------------------------------------------------------------------------- calibrator


class CalibratorConformance(_Suite):
    """Contract of ``pgc.roles.calibrator.Calibrator`` on a textured cube seen by 8 exactly posed cameras:
    the output has the same views (names, order, images, intrinsics), finite poses that stay within 2
    degrees and 5 cm of the exact ones; fewer than 3 views raise :class:`PGCDataError`."""

    MAX_ROTATION_DEG = 2.0
    MAX_SHIFT_M = 0.05

    @pytest.fixture(scope="class")
    @classmethod
    def capture(cls):
        from pgc.testing.capture_scenes import textured_box_capture

        return textured_box_capture()

    def test_same_views_and_finite_poses_near_the_truth(self, implementation, capture):
        out = implementation.calibrate(capture)
        assert [v.camera.name for v in out.capture.views] == [v.camera.name for v in capture.views]
        for before, after in zip(capture.views, out.capture.views):
            a, b = before.camera, after.camera
            assert np.all(np.isfinite(b.R)) and np.all(np.isfinite(b.t))
            np.testing.assert_array_equal(b.K, a.K)
            assert (b.width, b.height) == (a.width, a.height)
            np.testing.assert_array_equal(after.image, before.image)
            np.testing.assert_allclose(b.R @ b.R.T, np.eye(3), atol=1e-6)
            angle = np.degrees(np.arccos(np.clip((np.trace(a.R.T @ b.R) - 1) / 2, -1.0, 1.0)))
            assert angle < self.MAX_ROTATION_DEG, (a.name, angle)
            assert np.linalg.norm(b.center - a.center) < self.MAX_SHIFT_M, a.name
        assert all(np.all(np.isfinite(np.asarray(v, float))) for v in out.figures.values()
                   if isinstance(v, (int, float)))

    def test_too_few_views_raise(self, implementation, capture):
        from dataclasses import replace

        with pytest.raises(PGCDataError):
            implementation.calibrate(replace(capture, views=capture.views[:2]))


SUITES = {"filter": FilterConformance, "metric": MetricConformance, "brdf": BRDFConformance,
          "simulator": SimulatorConformance, "splat_renderer": SplatRendererConformance,
          "albedo_estimator": AlbedoEstimatorConformance, "pbr_renderer": PBRRendererConformance,
          "reconstructor": ReconstructorConformance, "scene_renderer": SceneRendererConformance,
          "calibrator": CalibratorConformance}
"""Role -> its conformance suite."""
