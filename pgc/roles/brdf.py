"""Role ``brdf``: a reflectance model with named parameters, bounds and initial values.

Contract
- Directions in the local shading frame (z = surface normal), unit vectors, arrays of shape (..., 3).
- :meth:`BRDF.eval_cos` returns ``f(wi, wo) * max(cos theta_i, 0)`` (linear RGB, shape (..., 3)), zero when
  either direction is below the surface; finite for every input (grazing angles, parameters at bounds).
- ``backend`` selects the array library of the inputs and the output: "numpy", "torch", "jax"; gradients
  flow through the torch/jax versions (a backend evaluates the same maths on its own arrays by passing its
  :class:`pgc.arrays.ArrayOps` subclass to :mod:`pgc.brdfs.maths`, as the Mitsuba BSDFs do).
- ``base_color`` is the spatially varying diffuse albedo sigma_d (..., 3); ``params`` maps every name of
  :attr:`BRDF.parameters` to a scalar or RGB value (broadcastable).
- Energy: for every wo, the hemispherical integral of eval_cos over wi is at most 1 per channel when
  colours are at most 1 (white furnace).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

from pgc.roles._base import RoleImplementation


@dataclass(frozen=True)
class BRDFParameter:
    name: str
    size: int
    """1 for a scalar, 3 for an RGB colour."""
    lower: float
    upper: float
    init: tuple[float, ...]
    """Initial value (the paper's), length ``size``."""
    description: str = ""


class BRDF(RoleImplementation, ABC):
    role = "brdf"
    parameters: ClassVar[tuple[BRDFParameter, ...]] = ()

    def initial_params(self) -> dict[str, Any]:
        return {p.name: (p.init[0] if p.size == 1 else list(p.init)) for p in self.parameters}

    @abstractmethod
    def eval_cos(self, wi: Any, wo: Any, base_color: Any, params: dict[str, Any], backend: str = "numpy") -> Any:
        """``f(wi, wo) max(cos theta_i, 0)`` in the local frame, arrays of ``backend``."""
