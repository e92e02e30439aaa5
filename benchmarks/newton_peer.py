"""Newton's XPBD cloth (warp-lang + newton, CPU) on our scene: a benchmark peer only, never a dependency.

Install for the benchmark: ``pip install warp-lang==1.19.0 newton==1.8.0``; set ``WARP_CACHE_PATH`` to keep
its kernel cache out of the home directory (first compile 15-30 s).

Why Newton needs other settings than the paper's: ``SolverXPBD`` updates springs as a plain Jacobi sweep
(every spring's correction is added, neither averaged per vertex nor relaxed), which converges only when
the largest eigenvalue of ``D^-1 A`` (``A = J W J^T + alpha/h^2``, ``D`` its diagonal) is below 2
(:func:`jacobi_eigenvalue`). On our 5k t-shirt (20 mg vertices, 5 kN/m) that needs ~1300 substeps per
frame, where ``g h^2`` (7e-9 m) is below the float32 spacing of metre-sized coordinates and the cloth
freezes; at the paper's 30 substeps even 5 N/m springs diverge. For given masses the eigenvalue depends
on ``stiffness x h^2`` only, so the benchmark runs both sides with softer springs at more substeps
(``bench_simulator.PRESETS[...]["newton"]``).
"""

from __future__ import annotations

import os
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

from pgc.sim.model import ClothModel
from pgc.sim.options import XPBDOptions
from pgc.types import Mesh


def available() -> bool:
    from importlib.util import find_spec

    return find_spec("newton") is not None and find_spec("warp") is not None


def jacobi_eigenvalue(model: ClothModel, h: float) -> float:
    """Largest eigenvalue of ``D^-1 A`` for the XPBD constraint system of ``model`` at the rest shape and
    substep ``h`` (s): ``A = J W J^T + diag(alpha / h^2)``, ``D = diag(A)``. An un-averaged Jacobi sweep
    (Newton's ``solve_springs``) converges iff it is below 2 (dimensionless)."""
    x = model.rest_positions
    d = x[model.ci] - x[model.cj]
    n = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    c, v = len(model.ci), len(x)
    cols = np.concatenate([3 * model.ci[:, None] + np.arange(3), 3 * model.cj[:, None] + np.arange(3)], 1)
    jac = sp.csr_matrix((np.concatenate([n, -n], 1).ravel(), (np.repeat(np.arange(c), 6), cols.ravel())),
                        shape=(c, 3 * v))
    a = (jac @ sp.diags(np.repeat(model.inv_mass, 3)) @ jac.T + sp.diags(model.compliance / h**2)).tocsr()
    scale = sp.diags(1.0 / np.sqrt(a.diagonal()))
    return float(eigsh(scale @ a @ scale, k=1, which="LA", return_eigenvectors=False)[0])


def newton_settle(model: ClothModel, body: Mesh, frames: int, options: XPBDOptions, fps: float = 30.0
                  ) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """Drape the garment of ``model`` on the static ``body`` for ``frames`` frames with Newton's SolverXPBD.

    The same particles, masses, springs (stretch and bending, each with stiffness ``1 / compliance`` and the
    model's rest length), gravity, substeps, iterations, friction, velocity damping (applied to the
    particle velocities before each substep, as ours) and cloth-body gap (particle radius = our offset) as
    ours; no particle self-contact (ours has it off by default). The scene is moved so that the garment's
    centre is at the origin (float32 positions resolve ``g h^2`` there) and moved back. Returns the final
    positions (V, 3) and velocities (V, 3), the seconds per frame after a warm-up (compile) frame, the
    RMS XPBD residual ``C + alpha~ lam`` (m) of the springs after the last substep, ours' measure (Newton's
    multipliers, same sign and ``alpha~ = 1 / (ke h^2)`` convention, are read from its spring kernel's
    output during that substep), and the process CPU seconds per frame (all threads).
    """
    os.environ.setdefault("WARP_CACHE_PATH", "/tmp/pgc_warp_cache")
    import warp as wp

    wp.config.quiet = True
    import newton

    wp.set_device("cpu")
    centre = model.rest_positions.mean(axis=0)
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=tuple(options.gravity))
    cfg = builder.default_shape_cfg.copy()
    cfg.mu = options.friction
    builder.add_shape_mesh(body=-1, mesh=newton.Mesh((body.vertices - centre).astype(np.float32),
                                                     body.faces.reshape(-1)), cfg=cfg)
    x = model.rest_positions - centre
    builder.add_particles(x.tolist(), [(0.0, 0.0, 0.0)] * len(x), (1.0 / model.inv_mass).tolist(),
                          [options.collision_offset] * len(x))
    for i, j, rest, alpha in zip(model.ci.tolist(), model.cj.tolist(), model.rest.tolist(),
                                 model.compliance.tolist()):
        builder.add_spring(i, j, 1.0 / alpha, 0.0, 0.0)
        builder.spring_rest_length[-1] = rest
    newton_model = builder.finalize(device="cpu")
    newton_model.soft_contact_mu = newton_model.particle_mu = options.friction  # contact mu = their mean
    newton_model.particle_max_radius, newton_model.particle_grid = 0.0, None  # no particle-particle contact
    solver = newton.solvers.SolverXPBD(newton_model, iterations=options.iterations)
    s0, s1, control = newton_model.state(), newton_model.state(), newton_model.control()
    pipeline = newton.CollisionPipeline(newton_model)
    contacts = pipeline.contacts()
    dt = 1.0 / (fps * options.substeps)
    damping = float(np.exp(-options.damping * dt))

    def substep() -> None:
        nonlocal s0, s1
        s0.particle_qd.numpy()[:] *= damping  # a view of the CPU array: damps in place
        s0.clear_forces()
        pipeline.collide(s0, contacts)
        solver.step(s0, s1, control, contacts, dt)
        s0, s1 = s1, s0

    from newton._src.solvers.xpbd.kernels import solve_springs  # the multipliers stay inside SolverXPBD.step

    launch, lam = wp.launch, {}

    def spy(kernel: object, *args: object, **kwargs: object) -> object:
        if kernel is solve_springs:
            lam["springs"] = kwargs["outputs"][0]  # updated in place over the iterations of the substep
        return launch(kernel, *args, **kwargs)

    for _ in range(options.substeps):  # compile
        substep()
    start, cpu_start = time.perf_counter(), time.process_time()
    for _ in range((frames - 1) * options.substeps - 1):
        substep()
    wp.launch = spy  # the last substep: keep its spring multipliers
    try:
        substep()
    finally:
        wp.launch = launch
    seconds = (time.perf_counter() - start) / max(frames - 1, 1)
    cpu_seconds = (time.process_time() - cpu_start) / max(frames - 1, 1)
    x = s0.particle_q.numpy().astype(np.float64)
    c = np.linalg.norm(x[model.ci] - x[model.cj], axis=1) - model.rest
    res = c + model.compliance / dt**2 * lam["springs"].numpy().astype(np.float64)
    return (x + centre, s0.particle_qd.numpy().astype(np.float64), seconds, float(np.sqrt(np.mean(res**2))),
            cpu_seconds)
