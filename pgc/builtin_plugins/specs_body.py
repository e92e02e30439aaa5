"""Registration of the built-in body models 'anny' (the default) and 'smplx' (light: pgc core + pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options, count
from pgc.registry import ImplementationSpec

ANNY_TOPOLOGIES = ("notoes_collapse3pc", "notoes_collapse5pc", "notoes_collapse10pc", "notoes")
"""Anny's toe-less body meshes, coarse to fine (369, 615, 1229 and 12 272 vertices)."""


class AnnyOptions(Options):
    """NAVER's Anny body (MakeHuman data, CC0) with the CMU motion-capture rig."""

    topology: Literal[ANNY_TOPOLOGIES] = Field(  # type: ignore[valid-type]
        "notoes_collapse10pc", description="mesh resolution: notoes_collapse3pc / 5pc / 10pc (369 / 615 / 1229 "
                                           "vertices) or notoes (12 272 vertices)")


class SmplxOptions(Options):
    """An SMPL-family body from the user's licensed model file."""

    model_path: str = Field(..., min_length=1, description="the licensed SMPL model file (SMPL_NEUTRAL.pkl, "
                                                           "SMPL_MALE.pkl, ... or the same arrays in an .npz)")
    num_betas: int = count(10, 1, 300, "shape coefficients used (betas)")
    beta_range: float = Field(3.0, gt=0.0, le=10.0, description="each beta is limited to [-beta_range, "
                                                                "beta_range] standard deviations")


SPECS = [
    ImplementationSpec(
        role="body_model", name="anny", factory="pgc.body.anny:AnnyBody",
        description="Anny (NAVER, Apache-2.0, MakeHuman CC0 data): phenotypes gender, age, muscle, weight, "
                    "height, proportions; CMU rig",
        options="pgc.builtin_plugins.specs_body:AnnyOptions", requires=("anny", "torch", "roma"), extra="body"),
    ImplementationSpec(
        role="body_model", name="smplx", factory="pgc.body.smpl:SmplBody",
        description="SMPL from the user's licensed model file (model_path), through the smplx package",
        options="pgc.builtin_plugins.specs_body:SmplxOptions", requires=("smplx", "torch"), extra="body"),
]
