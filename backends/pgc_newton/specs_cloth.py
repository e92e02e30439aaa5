"""Registration of ``newton-vbd`` (light: pgc core and pydantic only; Warp compiles its kernels on first use)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options, count
from pgc.registry import ImplementationSpec


class NewtonClothOptions(Options):
    """Cloth by Vertex Block Descent (Chen et al. 2024) in Newton: StVK membrane triangles, dihedral bending,
    cloth-body and cloth-cloth contact as one triangle-mesh contact problem (the body enters as kinematic
    triangles). Defaults are the independent ground truth's cloth (docs/simulation.md, "Independent truth"),
    deliberately not the XPBD defaults."""

    substeps: int = count(10, 1, 1000, "substeps per motion frame")
    iterations: int = count(10, 1, 1000, "VBD iterations per substep")
    density: float = Field(0.2, gt=0.0, description="fabric areal density (kg/m^2)")
    stretch_stiffness: float = Field(2.0e4, gt=0.0, description="membrane stiffness tri_ke (N/m): StVK shear "
                                     "modulus times thickness")
    area_stiffness: float = Field(2.0e4, gt=0.0, description="membrane area stiffness tri_ka (N/m): StVK Lame "
                                  "lambda times thickness")
    stretch_damping: float = Field(1.0e-5, ge=0.0, description="membrane Rayleigh damping tri_kd (s)")
    bend_stiffness: float = Field(5.0e-5, ge=0.0, description="dihedral bending stiffness edge_ke (N m / rad)")
    bend_damping: float = Field(1.0e-5, ge=0.0, description="bending Rayleigh damping edge_kd (s)")
    gravity: tuple[float, float, float] = Field((0.0, -9.81, 0.0), description="gravity (m/s^2), +Y up")
    contact_stiffness: float = Field(1.0e4, gt=0.0, description="contact penalty stiffness (N/m)")
    contact_damping: float = Field(1.0e-6, ge=0.0, description="contact damping (s)")
    friction: float = Field(0.4, ge=0.0, description="Coulomb friction coefficient (cloth-body, cloth-cloth)")
    contact_distance: float = Field(0.003, gt=0.0, description="distance (m) at which the cloth starts to touch "
                                    "the body or itself (Newton's particle_self_contact_margin)")
    contact_gap: float = Field(0.012, ge=0.0, description="extra contact detection distance (m) beyond "
                               "contact_distance (Newton's particle_self_contact_gap)")
    settle_frames: int = count(10, 0, 10_000, "frames simulated on the capture pose before the motion")
    blend_frames: int = count(10, 0, 10_000, "frames blending the body from the capture pose into motion frame 0 "
                              "when they differ")
    device: Literal["cpu", "cuda"] = Field("cpu", description="Warp device")


SPECS = [
    ImplementationSpec(
        role="simulator", name="newton-vbd", factory="pgc_newton.cloth:NewtonVBDSimulator",
        description="Vertex Block Descent cloth in Newton on Warp: FEM membrane, dihedral bending, body and self "
                    "contact; an integrator independent of the XPBD simulators",
        options="pgc_newton.specs_cloth:NewtonClothOptions", requires=("newton", "warp"), extra="newton"),
]
