"""The array operations (:class:`pgc.arrays.ArrayOps`) on Dr.Jit arrays, so that :mod:`pgc.brdfs.maths`
evaluates inside Mitsuba BSDFs with the same formulas as the numpy/torch/JAX evaluation."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pgc.arrays import LUMINANCE, ArrayOps
from pgc_mitsuba.runtime import mitsuba


class DrJitOps(ArrayOps):
    """The operations of :class:`pgc.arrays.ArrayOps` that the BRDF maths uses, on Dr.Jit arrays (``Float``
    scalar fields, ``Vector3f`` directions, ``Color3f`` colours)."""

    name = "drjit"

    def __init__(self, dr: Any, mi: Any) -> None:
        super().__init__(dr)
        self.mi = mi

    def where(self, cond: Any, a: Any, b: Any) -> Any:
        return self.xp.select(cond, a, b)

    def split(self, v: Any) -> tuple[Any, Any, Any]:
        return v.x, v.y, v.z

    def expand(self, s: Any) -> Any:
        return s

    def param(self, value: Any, like: Any = None) -> Any:
        """Python numbers become ``Float``, 3-sequences ``Color3f``; Dr.Jit arrays pass through."""
        if isinstance(value, (int, float)):
            return self.mi.Float(float(value))
        if isinstance(value, (list, tuple)):
            return self.mi.Color3f(*[float(v) for v in value])
        return value

    def luminance(self, c: Any) -> Any:
        return c[0] * LUMINANCE[0] + c[1] * LUMINANCE[1] + c[2] * LUMINANCE[2]


@lru_cache(maxsize=None)
def drjit_ops() -> DrJitOps:
    """The Dr.Jit namespace (Mitsuba imported in PGC's variant first, see :mod:`pgc_mitsuba.runtime`)."""
    mi = mitsuba()
    import drjit

    return DrJitOps(drjit, mi)
