"""The ``brdf`` role implementations: thin classes over the shared maths of :mod:`pgc.brdfs.maths`."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from pgc.arrays import LIBRARIES, array_ops
from pgc.brdfs.maths import EVALUATORS
from pgc.brdfs.parameters import PARAMETERS
from pgc.checks import require_finite
from pgc.errors import PGCConfigError, PGCDataError
from pgc.roles.brdf import BRDF, BRDFParameter


class ClothBRDF(BRDF):
    """A built-in cloth BRDF; ``model`` names its formula in :data:`pgc.brdfs.maths.EVALUATORS`.

    ``eval_cos(wi, wo, ...)``: ``wi`` toward the light, ``wo`` toward the viewer (local frame, z = normal),
    unit vectors (..., 3); returns ``f(wi, wo) max(cos theta_i, 0)`` (..., 3). Missing parameters take
    their initial values; unknown names are an error. ``backend``: "numpy", "torch" or "jax". NaN/Inf are
    refused in numpy inputs and in parameters given as numbers (tensors of the other backends are not inspected:
    that would synchronise or break tracing).
    """

    model: ClassVar[str] = ""

    def full_params(self, params: dict[str, Any] | None) -> dict[str, Any]:
        """``params`` completed with initial values; unknown names raise :class:`PGCDataError`."""
        params = dict(params or {})
        names = {p.name for p in self.parameters}
        unknown = sorted(set(params) - names - {"base_color"})
        if unknown:
            raise PGCDataError(f"brdf '{self.model}': unknown parameter(s) {unknown}; "
                               f"its parameters are {sorted(names) or '(none)'}")
        out = self.initial_params()
        out.update({k: v for k, v in params.items() if k in names})
        return out

    def eval_cos(self, wi: Any, wo: Any, base_color: Any, params: dict[str, Any], backend: str = "numpy") -> Any:
        full = self.full_params(params)
        where = f"brdf '{self.model}'"
        if backend == "numpy":
            for name, value in (("wi", wi), ("wo", wo), ("base_color", base_color)):
                require_finite(where, name, value)
        for name, value in full.items():
            if isinstance(value, (int, float, list, tuple, np.ndarray)):
                require_finite(where, f"parameter '{name}'", value)
        if backend not in LIBRARIES:
            raise PGCConfigError(f"{where}: unknown BRDF backend '{backend}'; use one of: {', '.join(LIBRARIES)}")
        return EVALUATORS[self.model](array_ops(backend), wi, wo, base_color, full)


class LambertianBRDF(ClothBRDF):
    model = "lambertian"
    parameters: ClassVar[tuple[BRDFParameter, ...]] = PARAMETERS["lambertian"]


class DisneyBRDF(ClothBRDF):
    """Disney diffuse + Disney sheen. Not energy conserving by design: the diffuse retro-reflection term
    (F_D90 up to 2.5 at roughness 1) plus the additive sheen reflect up to 1.97 of the incident light at
    grazing view (cos_o = 0.01, parameters at their bounds; measured on the conformance suite's grid)."""

    model = "disney"
    parameters: ClassVar[tuple[BRDFParameter, ...]] = PARAMETERS["disney"]
    furnace_limit: ClassVar[float] = 2.0


class PGCSheenBRDF(ClothBRDF):
    """The paper's model: sheen layer + H_s-scaled Disney diffuse. The sheen layer and its scaling conserve
    energy exactly; the Disney diffuse base keeps its retro-reflection, so at roughness 1 and grazing view
    the total reaches 1.14 (measured on the conformance suite's grid); at roughness <= 0.4 it is <= 1."""

    model = "pgc-sheen"
    parameters: ClassVar[tuple[BRDFParameter, ...]] = PARAMETERS["pgc-sheen"]
    furnace_limit: ClassVar[float] = 1.15
