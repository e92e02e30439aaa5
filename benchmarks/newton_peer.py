"""Newton's XPBD cloth (warp-lang + newton, CPU) on our scene: a benchmark peer only, never a dependency.

Install for the benchmark: ``pip install warp-lang==1.19.0 newton==1.8.0``; set ``WARP_CACHE_PATH`` to keep
its kernel cache out of the home directory (first compile 15-30 s).
"""

from __future__ import annotations

import os
import time

import numpy as np

from pgc.sim.options import XPBDOptions
from pgc.types import Mesh


def available() -> bool:
    from importlib.util import find_spec

    return find_spec("newton") is not None and find_spec("warp") is not None


def newton_settle(garment: Mesh, body: Mesh, frames: int, options: XPBDOptions, fps: float = 30.0
                  ) -> tuple[np.ndarray, float]:
    """Drape ``garment`` on the static ``body`` for ``frames`` frames with Newton's SolverXPBD.

    Same substeps, iterations, density, edge spring stiffness, gravity, friction and cloth-body gap
    (particle radius = our offset) as ``options``; Newton's bending model differs (its XPBD has no
    cross-edge springs), so ``bend_stiffness`` maps to nothing. Returns the final positions (V, 3) and
    seconds per frame (after a warm-up frame that compiles the kernels).
    """
    os.environ.setdefault("WARP_CACHE_PATH", "/tmp/pgc_warp_cache")
    import warp as wp

    wp.config.quiet = True
    import newton

    wp.set_device("cpu")
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=tuple(options.gravity))
    cfg = builder.default_shape_cfg.copy()
    cfg.mu = options.friction
    builder.add_shape_mesh(body=-1, mesh=newton.Mesh(body.vertices.astype(np.float32), body.faces.reshape(-1)),
                           cfg=cfg)
    builder.add_cloth_mesh(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
                           vertices=[wp.vec3(*v) for v in garment.vertices.astype(np.float32)],
                           indices=garment.faces.reshape(-1).tolist(), density=options.density,
                           tri_ke=0.0, tri_ka=0.0, tri_kd=0.0, edge_ke=0.0, edge_kd=0.0,
                           add_springs=True, spring_ke=options.stretch_stiffness, spring_kd=0.0,
                           particle_radius=options.collision_offset)
    model = builder.finalize(device="cpu")
    model.soft_contact_mu = options.friction
    solver = newton.solvers.SolverXPBD(model, iterations=options.iterations)
    s0, s1, control = model.state(), model.state(), model.control()
    pipeline = newton.CollisionPipeline(model)
    contacts = pipeline.contacts()
    dt = 1.0 / (fps * options.substeps)

    def frame() -> None:
        nonlocal s0, s1
        for _ in range(options.substeps):
            s0.clear_forces()
            pipeline.collide(s0, contacts)
            solver.step(s0, s1, control, contacts, dt)
            s0, s1 = s1, s0

    frame()  # compile
    start = time.perf_counter()
    for _ in range(frames - 1):
        frame()
    seconds = (time.perf_counter() - start) / max(frames - 1, 1)
    return s0.particle_q.numpy().astype(np.float64), seconds
