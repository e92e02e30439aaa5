"""Options of the XPBD simulators (shared by ``xpbd-torch`` and ``xpbd-jax``). Light: pydantic only."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options, count


class XPBDOptions(Options):
    """XPBD cloth (Macklin et al. 2016) on an animated body. Defaults are the paper's settings."""

    substeps: int = count(30, 1, 1000, "substeps per motion frame (paper: 30 at 30 fps)")
    iterations: int = count(20, 1, 1000, "constraint iterations per substep (paper: 20)")
    solver: Literal["coloured", "jacobi"] = Field(
        "coloured", description="parallel update: Gauss-Seidel per graph colour, or Jacobi with relaxation "
        "(default: colouring, which reached a lower residual per unit time in benchmarks/bench_simulator.py)")
    relaxation: float = Field(1.5, gt=0.0, lt=2.0, description="Jacobi over-relaxation factor omega")
    density: float = Field(0.15, gt=0.0, description="fabric areal density (kg/m^2)")
    stretch_stiffness: float = Field(5.0e3, gt=0.0, allow_inf_nan=True, description=(
        "edge spring stiffness (N/m); compliance = 1 / stiffness; inf gives rigid edges (zero compliance)"))
    bend_stiffness: float = Field(5.0, ge=0.0, allow_inf_nan=True, description=(
        "spring stiffness across interior edges (N/m); inf gives rigid bending"))
    bend_scale: float = Field(1.0, ge=0.0, description="multiplier of bend_stiffness (paper: 10 for thick garments)")
    damping: float = Field(1.0, ge=0.0, description="velocity damping rate (1/s): v *= exp(-damping * h)")
    gravity: tuple[float, float, float] = Field((0.0, -9.81, 0.0), description="gravity (m/s^2), +Y up")
    collision_offset: float = Field(0.004, ge=0.0, description="cloth-body offset (m); paper: 0.4 cm")
    friction: float = Field(0.3, ge=0.0, description="Coulomb friction coefficient against the body")
    contact_radius: float = Field(0.05, gt=0.0, description="only vertices within this distance of the body "
                                  "surface (m) are collided: deeper penetrations are not resolved")
    candidates: int = count(8, 1, 256, "nearest body triangles per cloth vertex, found once per frame")
    self_collision: bool = Field(False, description="vertex-vertex self-collision (pairs found once per frame)")
    self_thickness: float = Field(0.004, gt=0.0, description="minimum distance between non-adjacent vertices (m)")
    settle_frames: int = count(10, 0, 10_000, "frames simulated on the capture pose before the motion")
    blend_frames: int = count(10, 0, 10_000, "frames blending the body from the capture pose into motion frame 0 "
                              "when they differ")
    sag_free: bool = Field(False, description="solve the sag-free rest shape on the capture pose first")
    sag_free_iterations: int = count(6, 1, 1000, "fixed-point iterations of the sag-free solve")
    dtype: Literal["float32", "float64"] = Field("float32", description="floating point precision")
