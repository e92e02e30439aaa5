"""The frame loop shared by the XPBD backends: schedule, per-frame collision candidates, figures."""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.roles.simulator import Simulation, Simulator
from pgc.sim.collision import (
    candidate_corners,
    penetration_fraction,
    self_collision_pairs,
    vertex_normals,
)
from pgc.sim.xpbd import FrameInput, StepSettings
from pgc.sim.model import STRETCH, ClothModel, build_cloth_model
from pgc.sim.options import XPBDOptions
from pgc.sim.schedule import body_schedule
from pgc.types import BodyMotion, Mesh


def constraint_groups(model: ClothModel, options: XPBDOptions, h: float) -> list[tuple[np.ndarray, ...]]:
    """The constraint groups of :mod:`pgc.sim.xpbd` (numpy): all constraints in one Jacobi sweep with
    shares ``omega / max(n_i, n_j)``, or one Gauss-Seidel group per graph colour (share 1)."""
    alpha_t = model.compliance / (h * h)

    def group(idx: np.ndarray, share: np.ndarray) -> tuple[np.ndarray, ...]:
        return model.ci[idx], model.cj[idx], model.rest[idx], alpha_t[idx], share

    if options.solver == "jacobi":
        return [group(np.arange(len(model.ci)), options.relaxation * model.jacobi_share)]
    return [group(idx, np.ones(len(idx))) for idx in model.colours]


class Stepper(ABC):
    """One backend's state (positions, velocities) and its frame step. Subclasses convert at the edge."""

    def __init__(self, model: ClothModel, settings: StepSettings, options: XPBDOptions) -> None:
        self.model, self.settings, self.options = model, settings, options
        self.groups = constraint_groups(model, options, settings.h)
        self.order = np.arange(len(model.ci)) if options.solver == "jacobi" else np.concatenate(model.colours)

    def in_model_order(self, per_group: list[np.ndarray]) -> np.ndarray:
        """Concatenate per-group values (C,) back into the model's constraint order."""
        out = np.empty(len(self.order))
        out[self.order] = np.concatenate(per_group)
        return out

    @abstractmethod
    def set_state(self, x: np.ndarray, v: np.ndarray) -> None:
        """Positions and velocities (V, 3), metres and metres per second."""

    @abstractmethod
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Current positions and velocities as float64 numpy (V, 3)."""

    @abstractmethod
    def advance(self, frame: FrameInput) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One frame on numpy inputs -> positions (V, 3), XPBD residuals and constraint values (C,) in the
        model's constraint order."""


def check_frame_rate(fps: float) -> None:
    """Refuse a NaN, infinite or non-positive frame rate (its time step would make the first frame diverge, which
    a simulator would report as a stiffness problem)."""
    if not (math.isfinite(fps) and fps > 0):
        raise PGCDataError(f"motion: fps must be a finite positive number (frames per second), got {fps}")


def check_finite_frame(x: np.ndarray, garment_name: str, frame: int) -> None:
    """Refuse a simulated frame with NaN or infinite positions (a diverged simulation)."""
    if not np.all(np.isfinite(x)):
        raise FloatingPointError(f"simulation of '{garment_name}' diverged at frame {frame}; lower the stiffness "
                                 "or raise substeps")


def step_settings(options: XPBDOptions, fps: float) -> StepSettings:
    """The substep settings at the motion's ``fps`` (checked by :func:`check_frame_rate`)."""
    check_frame_rate(fps)
    h = 1.0 / (fps * options.substeps)
    return StepSettings(options.substeps, options.iterations, h, math.exp(-options.damping * h),
                        options.collision_offset, options.friction, options.contact_radius,
                        0.5 * options.contact_radius, options.self_collision,
                        options.self_thickness)


class FrameRunner:
    """Steps a :class:`Stepper` through body frames, building the per-frame inputs on the CPU."""

    def __init__(self, stepper: Stepper, body_faces: np.ndarray) -> None:
        self.stepper, self.faces = stepper, np.asarray(body_faces, dtype=np.int64)
        m = stepper.model
        self.x = m.rest_positions.copy()
        self.exclude = {(int(a), int(b)) for a, b in zip(np.minimum(m.ci, m.cj), np.maximum(m.ci, m.cj))}
        stepper.set_state(self.x, np.zeros_like(self.x))

    def frame_input(self, body0: np.ndarray, body1: np.ndarray) -> FrameInput:
        opts = self.stepper.options
        corners = candidate_corners(self.x, 0.5 * (body0 + body1), self.faces, opts.candidates)
        if opts.self_collision:
            pairs, valid = self_collision_pairs(self.x, 2.0 * opts.self_thickness, self.exclude)
        else:
            pairs, valid = np.zeros((1, 2), np.int64), np.zeros(1, bool)
        return FrameInput(body0, body1, vertex_normals(body0, self.faces), vertex_normals(body1, self.faces),
                          corners, pairs, valid)

    def step(self, body0: np.ndarray, body1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.x, res, c = self.stepper.advance(self.frame_input(body0, body1))
        return self.x, res, c


def settle(stepper: Stepper, body: np.ndarray, body_faces: np.ndarray, frames: int) -> np.ndarray:
    """Positions after ``frames`` frames on a static body, starting at rest with zero velocity."""
    runner = FrameRunner(stepper, body_faces)
    for _ in range(frames):
        runner.step(body, body)
    return runner.x


class XPBDSimulator(Simulator):
    """XPBD cloth on an animated body (the frame loop); backends supply :meth:`make_stepper`."""

    Options = XPBDOptions
    options: XPBDOptions

    @abstractmethod
    def make_stepper(self, model: ClothModel, settings: StepSettings) -> Stepper:
        """The backend's stepper for ``model``."""

    def build_model(self, garment: Mesh, pinned: np.ndarray | None = None) -> ClothModel:
        o = self.options
        return build_cloth_model(garment, o.density, o.stretch_stiffness, o.bend_stiffness * o.bend_scale, pinned)

    def simulate(self, garment: Mesh, motion: BodyMotion, reporter: Reporter | None = None) -> Simulation:
        reporter = reporter or Reporter.silent()
        o = self.options
        settings = step_settings(o, motion.fps)
        model = self.build_model(garment)
        figures: dict[str, Any] = {"solver": o.solver, "substeps": o.substeps, "iterations": o.iterations}
        if o.sag_free:
            from pgc.sim.sagfree import solve_sag_free

            with reporter.stage("sag_free", total=o.sag_free_iterations) as st:
                model, history = solve_sag_free(
                    model, lambda m: settle(self.make_stepper(m, settings), motion.vertices[0].astype(np.float64),
                                            motion.faces, max(o.settle_frames, 1)),
                    o.sag_free_iterations, progress=st.progress)
                st.record(sag_mean=history[-1]["sag_mean"], sag_max=history[-1]["sag_max"])
            figures["sag_free"] = history
        schedule = body_schedule(motion, o.settle_frames, o.blend_frames)
        runner = FrameRunner(self.make_stepper(model, settings), motion.faces)
        stretch = model.kind == STRETCH
        out = np.empty((motion.num_frames, model.num_vertices, 3), dtype=np.float32)
        residual, strain, penetration = [], [], []
        n = len(schedule.vertices) - 1
        start = time.perf_counter()
        with reporter.stage("animate", total=n, vertices=model.num_vertices, frames=motion.num_frames) as st:
            for k in range(1, n + 1):
                body1 = schedule.vertices[k]
                x, res, c = runner.step(schedule.vertices[k - 1], body1)
                check_finite_frame(x, garment.name, k)
                t = k - schedule.first_motion
                if t >= 0:
                    out[t] = x
                    residual.append(float(np.sqrt(np.mean(res**2))))
                    rel = np.abs(c[stretch]) / np.maximum(model.rest[stretch], 1e-9)
                    strain.append((float(rel.max(initial=0.0)), float(np.percentile(rel, 99)) if rel.size else 0.0))
                    penetration.append(penetration_fraction(x, body1, motion.faces, o.collision_offset))
                st.progress(k, n, penetration=penetration[-1] if penetration else 0.0)
            seconds = time.perf_counter() - start
            figures.update(
                seconds=seconds, frames_per_second=n / seconds, simulated_frames=n,
                residual_rms=residual, max_stretch_strain=[a for a, _ in strain],
                p99_stretch_strain=[b for _, b in strain], penetration_fraction=penetration,
                max_penetration_fraction=max(penetration, default=0.0))
            st.record(frames_per_second=n / seconds, max_penetration_fraction=figures["max_penetration_fraction"])
        return Simulation(out, figures)
