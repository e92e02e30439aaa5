"""``xpbd-native`` (compiled C++/OpenMP XPBD): agreement with ``xpbd-jax``, determinism, physics, registration."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.registry import default_registry
from pgc.sim.driver import FrameRunner, step_settings
from pgc.sim.model import STRETCH, ClothModel
from pgc.testing.cloth_scenes import grid_cloth, moving_motion, uv_sphere
from pgc.types import BodyMotion, Mesh

pytest.importorskip("scipy")
native = pytest.importorskip("pgc_native.xpbd.simulator")

SPHERE = uv_sphere(0.25, rings=10, segments=20)
FAR_BODY = Mesh(np.array([[50.0, 50, 50], [51, 50, 50], [50, 51, 50]]), np.array([[0, 1, 2]]), name="far")


def jax_simulator(**options):
    pytest.importorskip("jax")
    from pgc_jax.xpbd.simulator import JaxXPBDSimulator

    return JaxXPBDSimulator(options)


def two_layers() -> Mesh:
    """Two 7 x 7 squares 3 mm apart above the sphere: the layers are not neighbours, so self-collision acts."""
    a, b = grid_cloth(7, 0.5, 0.28), grid_cloth(7, 0.5, 0.283)
    return Mesh(np.concatenate([a.vertices, b.vertices]), np.concatenate([a.faces, b.faces + len(a.vertices)]),
                name="two-layers")


def drape(cloth: Mesh, motion: BodyMotion, sim_native: bool, **options) -> tuple[np.ndarray, list[float]]:
    sim = native.NativeXPBDSimulator(options) if sim_native else jax_simulator(**options)
    out = sim.simulate(cloth, motion)
    return out.vertices, out.figures["residual_rms"]


@pytest.mark.agreement
@pytest.mark.parametrize("solver", ["coloured", "jacobi"])
@pytest.mark.parametrize("iterations", [1, 4])
def test_agrees_with_jax_in_float64_with_the_same_residuals(solver, iterations):
    """The same maths: positions to 1e-6 m and the per-frame XPBD residual to 1e-9 relative, in float64 over
    a draping run with a moving body (settle frames + 3 motion frames), for 1 and 4 iterations."""
    cloth, motion = grid_cloth(8, 0.5, 0.27), moving_motion(SPHERE, 3, velocity=(0.3, 0.0, 0.0))
    opts = {"substeps": 4, "iterations": iterations, "settle_frames": 2, "solver": solver, "dtype": "float64"}
    a, ra = drape(cloth, motion, True, **opts)
    b, rb = drape(cloth, motion, False, **opts)
    assert np.abs(a - b).max() < 1e-6
    np.testing.assert_allclose(ra, rb, rtol=1e-9)
    assert np.abs(a - cloth.vertices).max() > 0.01  # it moved: the comparison is not of two rest shapes


def test_self_collision_agrees_with_jax_and_acts():
    cloth, motion = two_layers(), moving_motion(SPHERE, 3, velocity=(0.2, 0.0, 0.0))
    opts = {"substeps": 4, "iterations": 3, "settle_frames": 2, "dtype": "float64", "self_collision": True,
            "self_thickness": 0.01}
    a, ra = drape(cloth, motion, True, **opts)
    b, rb = drape(cloth, motion, False, **opts)
    assert np.abs(a - b).max() < 1e-6
    np.testing.assert_allclose(ra, rb, rtol=1e-9)
    off, _ = drape(cloth, motion, True, **{**opts, "self_collision": False})
    assert np.abs(off - a).max() > 1e-3  # the layers were pushed apart


@pytest.mark.agreement
def test_float32_agrees_with_jax():
    cloth, motion = grid_cloth(8, 0.5, 0.27), moving_motion(SPHERE, 3, velocity=(0.3, 0.0, 0.0))
    opts = {"substeps": 4, "iterations": 3, "settle_frames": 2, "dtype": "float32"}
    a, _ = drape(cloth, motion, True, **opts)
    b, _ = drape(cloth, motion, False, **opts)
    assert a.dtype == np.float32 and np.abs(a - b).max() < 1e-4


@pytest.mark.parametrize("solver", ["coloured", "jacobi"])
def test_same_bytes_for_any_thread_count(solver):
    cloth, motion = two_layers(), moving_motion(SPHERE, 3, velocity=(0.3, 0.0, 0.0))
    runs = []
    for threads in (1, 2, 3, "auto"):
        sim = native.NativeXPBDSimulator({"substeps": 3, "iterations": 3, "settle_frames": 2, "solver": solver,
                                          "self_collision": True, "self_thickness": 0.01, "threads": threads})
        out = sim.simulate(cloth, motion)
        runs.append(out.vertices.tobytes() + np.array(out.figures["residual_rms"]).tobytes())
    assert runs[0] == runs[1] == runs[2] == runs[3]


@pytest.mark.parametrize("solver,iterations", [("coloured", 1), ("jacobi", 20)])
def test_hanging_mass_settles_at_the_compliance_fixed_point(solver, iterations):
    """A mass m on a spring of compliance alpha comes to rest extended by m g alpha (Hooke's law)."""
    m, alpha, g = 0.2, 0.05, 9.81
    sim = native.NativeXPBDSimulator({"substeps": 10, "iterations": iterations, "damping": 20.0,
                                      "dtype": "float64", "solver": solver})
    model = ClothModel(np.array([[0.0, 0, 0], [0, -0.5, 0]]), np.zeros((0, 3), np.int64), np.array([0.0, 1 / m]),
                       np.array([0]), np.array([1]), np.array([0.5]), np.array([alpha]), np.array([STRETCH]),
                       (np.array([0]),), np.array([1.0]))
    run = FrameRunner(sim.make_stepper(model, step_settings(sim.options, 10.0)), FAR_BODY.faces)
    for _ in range(25):
        x, res, _ = run.step(FAR_BODY.vertices, FAR_BODY.vertices)
    assert abs((-x[1, 1] - 0.5) - m * g * alpha) < 1e-6
    assert np.all(x[0] == 0.0)  # the pin holds
    assert np.abs(res).max() < (1e-9 if solver == "coloured" else 1e-6)  # Jacobi: error x 0.5 per iteration


def test_registered_light_and_validated():
    reg = default_registry()
    impl = reg.get("simulator", "xpbd-native")
    assert impl.available
    sim = reg.create("simulator", "xpbd-native", {"threads": 2, "substeps": 5})
    assert isinstance(sim, native.NativeXPBDSimulator) and sim.options.threads == 2
    with pytest.raises(ValueError):
        native.NativeXPBDSimulator({"threads": -1})
    assert native.NativeXPBDSimulator({}).options.threads == "auto"


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_avx512_and_baseline_builds_give_the_same_bytes(dtype):
    """The kernel's two builds (AVX-512, on a CPU that has it, and the baseline) agree byte for byte:
    no fused multiply-adds, IEEE division and square root in both."""
    from pgc_native.xpbd.library import avx512

    if not avx512():  # both runs would be the baseline build: nothing to compare
        pytest.skip("this CPU has no AVX-512")
    cloth, motion = two_layers(), moving_motion(SPHERE, 3, velocity=(0.3, 0.0, 0.0))
    runs = []
    for simd in (True, False):
        sim = native.NativeXPBDSimulator({"substeps": 3, "iterations": 4, "settle_frames": 2, "dtype": dtype,
                                          "self_collision": True, "self_thickness": 0.01, "simd": simd})
        out = sim.simulate(cloth, motion)
        runs.append(out.vertices.tobytes() + np.array(out.figures["residual_rms"]).tobytes())
    assert runs[0] == runs[1]
