"""XPBD dynamics with known answers, torch/JAX agreement, and hard cases (both backends)."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.sim.collision import signed_distance
from pgc.sim.driver import FrameRunner, XPBDSimulator, step_settings
from pgc.sim.model import STRETCH, ClothModel
from pgc.sim.options import XPBDOptions
from pgc.testing.cloth_scenes import grid_cloth, moving_motion, static_motion, uv_sphere
from pgc.types import Mesh

pytest.importorskip("scipy")
BACKENDS = ["torch", "jax"]
FAR_BODY = Mesh(np.array([[50.0, 50, 50], [51, 50, 50], [50, 51, 50]]), np.array([[0, 1, 2]]), name="far")
SPHERE = uv_sphere(0.25, rings=10, segments=20)
"""The body of the draping tests. xpbd-jax compiles one program per array shapes (garment, body, dtype,
solver), so the tests share a few garment and body sizes: same assertions, a fraction of the compiles."""
FAR_SPHERE = Mesh(SPHERE.vertices + 50.0, SPHERE.faces, name="far-sphere")


def simulator(backend: str, **options) -> XPBDSimulator:
    if backend == "torch":
        pytest.importorskip("torch")
        from pgc_torch.xpbd.simulator import TorchXPBDSimulator as cls
    else:
        pytest.importorskip("jax")
        from pgc_jax.xpbd.simulator import JaxXPBDSimulator as cls
    return cls(options)


def spring_model(mass: float, compliance: float, rest: float, start: float) -> ClothModel:
    """Particle 0 pinned at the origin, particle 1 of ``mass`` at (0, -start, 0) on a spring of ``rest`` length."""
    return ClothModel(np.array([[0.0, 0, 0], [0, -start, 0]]), np.zeros((0, 3), np.int64), np.array([0.0, 1 / mass]),
                      np.array([0]), np.array([1]), np.array([rest]), np.array([compliance]), np.array([STRETCH]),
                      (np.array([0]),), np.array([1.0]))


def runner(sim: XPBDSimulator, model: ClothModel, fps: float, body: Mesh = FAR_BODY) -> FrameRunner:
    return FrameRunner(sim.make_stepper(model, step_settings(sim.options, fps)), body.faces)


@pytest.mark.parametrize("backend", BACKENDS)
def test_spring_oscillation_is_implicit_euler_with_analytic_period(backend):
    """One spring, one iteration per substep: XPBD equals implicit Euler exactly,
    x_{n+1} = (x_n + h v_n) / (1 + w^2 h^2), and the period matches 2 pi / w (w^2 = k / m)."""
    k, m, h, substeps = 100.0, 1.0, 1e-3, 10
    sim = simulator(backend, substeps=substeps, iterations=1, gravity=(0, 0, 0), damping=0.0, dtype="float64",
                    solver="coloured")
    run = runner(sim, spring_model(m, 1 / k, 1.0, 1.1), 1 / (h * substeps))
    body = FAR_BODY.vertices
    xs = np.array([-run.step(body, body)[0][1, 1] for _ in range(140)]) - 1.0
    ref, x, v = [], 0.1, 0.0
    for _ in range(140 * substeps):
        x_new = (x + h * v) / (1 + k / m * h * h)
        v, x = (x_new - x) / h, x_new
        ref.append(x)
    np.testing.assert_allclose(xs, ref[substeps - 1::substeps], atol=1e-10)
    up = np.flatnonzero((xs[:-1] < 0) & (xs[1:] >= 0))  # upward zero crossings
    t = (up + xs[up] / (xs[up] - xs[up + 1])) * h * substeps  # linearly interpolated crossing times
    assert len(t) >= 2
    assert abs(np.diff(t).mean() - 2 * np.pi / np.sqrt(k / m)) < 0.002 * 2 * np.pi / np.sqrt(k / m)
    assert np.all(np.abs(xs) <= 0.1 + 1e-12)  # never gains amplitude


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("substeps,iterations,solver", [(3, 1, "coloured"), (10, 5, "coloured"), (10, 20, "jacobi")])
def test_compliance_fixed_point_is_hookes_law_independent_of_steps(backend, substeps, iterations, solver):
    """A hanging mass settles at extension m g alpha: XPBD's stiffness does not depend on the substeps or the
    iterations once each substep's solve converges (Gauss-Seidel: 1 iteration; Jacobi with omega = 1.5:
    error factor 0.5 per iteration, so 20)."""
    m, alpha, g = 0.2, 0.05, 9.81
    sim = simulator(backend, substeps=substeps, iterations=iterations, damping=20.0, dtype="float64",
                    solver=solver)
    run = runner(sim, spring_model(m, alpha, 0.5, 0.5), 10.0)
    for _ in range(25):
        x, _, _ = run.step(FAR_BODY.vertices, FAR_BODY.vertices)
    assert abs((-x[1, 1] - 0.5) - m * g * alpha) < 1e-6


def hanging_cloth(sim: XPBDSimulator, n: int = 10) -> tuple[FrameRunner, np.ndarray]:
    cloth = grid_cloth(n, 0.5, 1.0, vertical=True)
    return runner(sim, sim.build_model(cloth, pinned=np.array([0, n - 1])), 30.0, FAR_SPHERE), cloth.vertices


@pytest.mark.parametrize("backend", BACKENDS)
def test_hanging_cloth_converges_to_a_static_shape(backend):
    sim = simulator(backend, damping=2.0, substeps=10, iterations=10)
    run, rest = hanging_cloth(sim)
    xs = [run.step(FAR_SPHERE.vertices, FAR_SPHERE.vertices)[0] for _ in range(60)]
    speed = np.linalg.norm(xs[-1] - xs[-2], axis=1).max() * 30.0
    assert speed < 2e-3, speed
    assert np.abs(xs[-1][[0, 9]] - rest[[0, 9]]).max() == 0.0  # pins hold
    assert xs[-1][4, 1] < rest[4, 1] - 5e-4  # the top edge sags between the pinned corners
    assert np.all(np.isfinite(xs[-1]))


@pytest.mark.parametrize("backend", BACKENDS)
def test_energy_does_not_grow_without_forcing(backend):
    """Stretched cloth, no gravity, no damping, no body: kinetic + spring energy never exceeds its start."""
    sim = simulator(backend, gravity=(0, 0, 0), damping=0.0, substeps=10, iterations=5, dtype="float64",
                    stretch_stiffness=200.0, bend_stiffness=1.0)
    cloth = grid_cloth(7, 0.3)
    model = sim.build_model(cloth)
    run = runner(sim, model, 30.0, FAR_SPHERE)
    x0 = cloth.vertices * np.array([1.1, 1.0, 0.95])
    run.stepper.set_state(x0, np.zeros_like(x0))
    run.x = x0
    mass = 1 / model.inv_mass

    def energy(x, v):
        c = np.linalg.norm(x[model.ci] - x[model.cj], axis=1) - model.rest
        return 0.5 * (mass * (v * v).sum(1)).sum() + (0.5 * c * c / model.compliance).sum()

    e0 = energy(x0, np.zeros_like(x0))
    for _ in range(60):
        run.step(FAR_SPHERE.vertices, FAR_SPHERE.vertices)
        assert energy(*run.stepper.state()) <= e0 * (1 + 1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_garment_draped_on_static_body_comes_to_rest(backend):
    sim = simulator(backend, substeps=5, iterations=5, damping=5.0, friction=0.5, settle_frames=0)
    body = SPHERE
    out = sim.simulate(grid_cloth(10, 0.6, 0.26), static_motion(body, 80))
    speed = np.linalg.norm(out.vertices[-1] - out.vertices[-2], axis=1).max() * 30.0
    assert speed < 0.01, speed
    assert out.figures["max_penetration_fraction"] == 0.0
    gap = signed_distance(out.vertices[-1].astype(np.float64), body.vertices, body.faces)
    assert abs(gap.min() - 0.004) < 5e-4  # the contact sits at the 0.4 cm offset


@pytest.mark.agreement
@pytest.mark.parametrize("solver", ["jacobi", "coloured"])
def test_torch_and_jax_agree(solver):
    """Same inputs, same trajectories: float64 to 1e-9 m, float32 to 1e-4 m over 5 frames of draping."""
    body = SPHERE
    cloth = grid_cloth(7, 0.5, 0.27)
    motion = moving_motion(body, 3, velocity=(0.3, 0.0, 0.0))
    for dtype, tol in (("float64", 1e-9), ("float32", 1e-4)):
        opts = {"substeps": 4, "iterations": 3, "settle_frames": 2, "solver": solver, "dtype": dtype}
        a = simulator("torch", **opts).simulate(cloth, motion).vertices
        b = simulator("jax", **opts).simulate(cloth, motion).vertices
        assert np.abs(a - b).max() < tol, (dtype, np.abs(a - b).max())


# ---- hard cases -------------------------------------------------------------------------------------


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_compliance_and_large_time_steps_stay_finite(backend):
    body = SPHERE
    cloth = grid_cloth(10, 0.6, 0.3)
    for opts in ({"stretch_stiffness": float("inf"), "bend_stiffness": float("inf"), "substeps": 4, "iterations": 10},
                 {"substeps": 1, "iterations": 3}):
        motion = static_motion(body, 6)
        motion.fps = 4.0  # a 0.25 s step
        out = simulator(backend, settle_frames=0, **opts).simulate(cloth, motion)
        assert np.all(np.isfinite(out.vertices))
        assert np.abs(out.vertices).max() < 2.0  # no explosion
        assert out.figures["max_penetration_fraction"] <= 0.005


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_length_and_degenerate_edges_stay_finite(backend):
    cloth = grid_cloth(6, 0.4, 0.3)
    v = cloth.vertices.copy()
    v[7] = v[8]  # a zero-length edge
    v[14] = 0.5 * (v[13] + v[15])  # collinear: two degenerate triangles
    faces = np.concatenate([cloth.faces, [[20, 20, 21]]])  # a repeated-vertex triangle
    out = simulator(backend, substeps=5, iterations=5, settle_frames=0).simulate(
        Mesh(v, faces), static_motion(uv_sphere(0.2, rings=8, segments=16), 10))
    assert np.all(np.isfinite(out.vertices))
    assert np.abs(out.vertices).max() < 2.0


@pytest.mark.parametrize("backend", BACKENDS)
def test_body_starting_inside_the_garment_is_resolved(backend):
    """The cloth cuts through the top of the sphere at the start; collisions push it out."""
    out = simulator(backend, substeps=10, iterations=5, settle_frames=0).simulate(
        grid_cloth(10, 0.6, 0.2), static_motion(SPHERE, 6))
    assert np.all(np.isfinite(out.vertices))
    assert out.figures["penetration_fraction"][-1] <= 0.005


@pytest.mark.parametrize("backend", BACKENDS)
def test_fast_motion_no_explosion_no_penetration(backend):
    """The sphere under the cloth accelerates sideways at 3 m/s: stays finite, penetration under 0.5 %."""
    body = SPHERE
    sim = simulator(backend, substeps=10, iterations=5, settle_frames=3, friction=0.5)
    out = sim.simulate(grid_cloth(10, 0.6, 0.27), moving_motion(body, 8, velocity=(3.0, 0.0, 0.0)))
    assert np.all(np.isfinite(out.vertices))
    assert max(out.figures["penetration_fraction"]) <= 0.005
    assert np.linalg.norm(np.diff(out.vertices, axis=0), axis=2).max() < 0.5  # no frame jumps 0.5 m


def test_options_reject_unknown_and_bad_values():
    with pytest.raises(ValueError):
        XPBDOptions(substepz=3)
    with pytest.raises(ValueError):
        XPBDOptions(relaxation=2.5)
