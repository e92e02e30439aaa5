"""``newton-vbd``: cloth on an animated body by Newton's Vertex Block Descent solver (Warp kernels).

The garment is a Newton cloth mesh (StVK membrane triangles, dihedral bending edges). The body enters the
same model as a second triangle mesh whose particles are kinematic (not ACTIVE, massless): its vertices are
set at the end of every substep, interpolated linearly between motion frames (within a substep they stand
still, so friction sees the body at rest), and the solver's triangle-mesh contact
(vertex-triangle and edge-edge, with friction) keeps the cloth off it and off itself. The frame schedule
(settle on the capture pose, blend into the motion) is :func:`pgc.sim.schedule.body_schedule`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import warp as wp

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.roles.simulator import Simulation, Simulator
from pgc.sim.collision import penetration_fraction
from pgc.sim.schedule import body_schedule
from pgc.types import BodyMotion, Mesh
from pgc_newton.specs_cloth import NewtonClothOptions

wp.config.quiet = True  # no line per compiled module


@wp.kernel
def _place_body(body0: wp.array(dtype=wp.vec3), body1: wp.array(dtype=wp.vec3), s: float, offset: int,
                q: wp.array(dtype=wp.vec3)):
    """The kinematic body's particles (after ``offset``) at the fraction ``s`` of the way from body0 to body1."""
    i = wp.tid()
    q[offset + i] = body0[i] + s * (body1[i] - body0[i])


class NewtonVBDSimulator(Simulator):
    """VBD cloth in Newton; one :class:`NewtonCloth` per simulation."""

    Options = NewtonClothOptions
    options: NewtonClothOptions

    def simulate(self, garment: Mesh, motion: BodyMotion, reporter: Reporter | None = None) -> Simulation:
        from pgc.sim.driver import check_finite_frame, check_frame_rate

        check_frame_rate(motion.fps)
        reporter = reporter or Reporter.silent()
        o = self.options
        schedule = body_schedule(motion, o.settle_frames, o.blend_frames)
        start = time.perf_counter()
        cloth = NewtonCloth(garment, schedule.vertices[0], motion.faces, o)
        build = time.perf_counter() - start
        out = np.empty((motion.num_frames, len(garment.vertices), 3), dtype=np.float32)
        penetration: list[float] = []
        n = len(schedule.vertices) - 1
        start = time.perf_counter()
        with reporter.stage("animate", total=n, vertices=len(garment.vertices), frames=motion.num_frames) as st:
            for k in range(1, n + 1):
                x = cloth.frame(schedule.vertices[k - 1], schedule.vertices[k], 1.0 / motion.fps)
                check_finite_frame(x, garment.name, k)
                t = k - schedule.first_motion
                if t >= 0:
                    out[t] = x
                    penetration.append(penetration_fraction(x, schedule.vertices[k], motion.faces,
                                                            0.5 * o.contact_distance))
                st.progress(k, n, penetration=penetration[-1] if penetration else 0.0)
            seconds = time.perf_counter() - start
        figures: dict[str, Any] = {
            "solver": "vbd", "substeps": o.substeps, "iterations": o.iterations, "device": o.device,
            "build_seconds": build, "seconds": seconds, "frames_per_second": n / seconds, "simulated_frames": n,
            "penetration_fraction": penetration, "max_penetration_fraction": max(penetration, default=0.0)}
        return Simulation(out, figures)


class NewtonCloth:
    """A Newton model of one garment (active particles first) and one body (kinematic particles after)."""

    def __init__(self, garment: Mesh, body: np.ndarray, body_faces: np.ndarray, options: NewtonClothOptions):
        import newton

        self.options = options
        if options.device == "cuda" and wp.get_cuda_device_count() == 0:
            raise PGCDataError("newton-vbd: option device = 'cuda' but Warp finds no CUDA device; use 'cpu'")
        self.device = wp.get_device(options.device)
        o = options
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=tuple(o.gravity))
        self.n_cloth = len(garment.vertices)
        builder.add_cloth_mesh(
            pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
            vertices=np.asarray(garment.vertices, np.float32), indices=np.asarray(garment.faces).ravel().tolist(),
            density=o.density, tri_ke=o.stretch_stiffness, tri_ka=o.area_stiffness, tri_kd=o.stretch_damping,
            edge_ke=o.bend_stiffness, edge_kd=o.bend_damping, particle_radius=o.contact_distance)
        builder.add_cloth_mesh(  # the body: kinematic triangles (no mass, no elasticity), moved every substep
            pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
            vertices=np.asarray(body, np.float32), indices=np.asarray(body_faces).ravel().tolist(), density=0.0,
            tri_ke=0.0, tri_ka=0.0, tri_kd=0.0, edge_ke=0.0, edge_kd=0.0, particle_radius=o.contact_distance)
        active = int(newton.ParticleFlags.ACTIVE)
        for i in range(self.n_cloth, len(builder.particle_q)):
            builder.particle_flags[i] = int(builder.particle_flags[i]) & ~active
        builder.color(include_bending=True)
        self.model = builder.finalize(device=self.device)
        self.model.soft_contact_ke = o.contact_stiffness
        self.model.soft_contact_kd = o.contact_damping
        self.model.soft_contact_mu = o.friction
        self.solver = newton.solvers.SolverVBD(
            self.model, iterations=o.iterations, particle_enable_self_contact=True,
            particle_self_contact_margin=o.contact_distance, particle_self_contact_gap=o.contact_gap,
            particle_enable_tile_solve=self.device.is_cuda)
        self.states = (self.model.state(), self.model.state())
        self.control = self.model.control()
        self.n_body = len(body)
        self.body0 = wp.array(np.asarray(body, np.float32), dtype=wp.vec3, device=self.device)
        self.body1 = wp.array(np.asarray(body, np.float32), dtype=wp.vec3, device=self.device)
        self.graph, self.graph_dt, self.loaded = None, 0.0, False

    def frame(self, body0: np.ndarray, body1: np.ndarray, dt: float) -> np.ndarray:
        """Advance one frame of ``dt`` seconds while the body moves from ``body0`` to ``body1`` (B, 3); returns
        the garment's vertices (V, 3) float32. The frame's substeps run as one Warp graph (captured on the second
        call, once the first has loaded every kernel; replayed without Python on the CPU too)."""
        self.body0.assign(np.asarray(body0, np.float32))
        self.body1.assign(np.asarray(body1, np.float32))
        if self.graph is not None and self.graph_dt == dt:
            wp.capture_launch(self.graph)
        elif self.loaded:
            with wp.ScopedCapture(device=self.device) as capture:
                self._substeps(dt)
            self.graph, self.graph_dt = capture.graph, dt
            wp.capture_launch(self.graph)
        else:
            self._substeps(dt)
            self.loaded = True
        return self.states[0].particle_q.numpy()[: self.n_cloth].astype(np.float32)

    def _substeps(self, dt: float) -> None:
        o = self.options
        h = dt / o.substeps
        state_in, state_out = self.states
        for s in range(1, o.substeps + 1):
            for state in (state_in, state_out):  # the kinematic particles hold their place through the substep
                wp.launch(_place_body, dim=self.n_body, device=self.device,
                          inputs=[self.body0, self.body1, s / o.substeps, self.n_cloth, state.particle_q])
            state_in.clear_forces()
            self.solver.step(state_in, state_out, self.control, None, h)
            state_in, state_out = state_out, state_in
        if state_in is not self.states[0]:  # an odd count: the result back into the first state
            wp.copy(self.states[0].particle_q, state_in.particle_q)
            wp.copy(self.states[0].particle_qd, state_in.particle_qd)

