"""Array namespaces for the BRDF maths: one formula, several array libraries.

The maths in :mod:`pgc.brdfs.maths` works on *scalar fields* (one value per direction pair) and on
*colours*. A namespace supplies the handful of element-wise operations it needs and the two places where
libraries differ: how a 3-vector is split into components and how a scalar field is broadcast against a
colour. numpy/torch/jax hold vectors and colours as arrays with a trailing axis of 3 (:func:`namespace`);
a backend with other array types subclasses :class:`BrdfOps` and passes its object to the maths (the
Mitsuba backend's Dr.Jit namespace, ``pgc_mitsuba.ops``, holds ``Vector3f`` / ``Color3f`` values).

Libraries are imported lazily, when a namespace is first requested.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pgc.errors import PGCConfigError

LUMINANCE = (0.212671, 0.715160, 0.072169)
"""Linear-sRGB luminance weights (Mitsuba's ``luminance``), used by the Disney sheen tint and lobe weights."""


class BrdfOps:
    """Element-wise operations over one array library with a trailing colour/vector axis of 3."""

    name = "numpy"

    def __init__(self, module: Any) -> None:
        self.m = module

    def sqrt(self, x: Any) -> Any:
        return self.m.sqrt(x)

    def exp(self, x: Any) -> Any:
        return self.m.exp(x)

    def maximum(self, x: Any, y: float) -> Any:
        return self.m.maximum(x, y)

    def minimum(self, x: Any, y: float) -> Any:
        return self.m.minimum(x, y)

    def clip(self, x: Any, lo: float, hi: float) -> Any:
        return self.m.clip(x, lo, hi)

    def where(self, cond: Any, a: Any, b: Any) -> Any:
        return self.m.where(cond, a, b)

    def split(self, v: Any) -> tuple[Any, Any, Any]:
        """Components of a (..., 3) vector."""
        return v[..., 0], v[..., 1], v[..., 2]

    def expand(self, s: Any) -> Any:
        """A scalar field (...,) made broadcastable against colours (..., 3); Python numbers unchanged."""
        return s if isinstance(s, (int, float)) else s[..., None]

    def param(self, value: Any, like: Any) -> Any:
        """A parameter value (float, 3-list, array) as an array of ``like``'s library and dtype."""
        return self.m.asarray(value, dtype=like.dtype)

    def luminance(self, c: Any) -> Any:
        return c[..., 0] * LUMINANCE[0] + c[..., 1] * LUMINANCE[1] + c[..., 2] * LUMINANCE[2]


class TorchBrdfOps(BrdfOps):
    name = "torch"

    def maximum(self, x: Any, y: float) -> Any:
        return self.m.clamp(x, min=y)

    def minimum(self, x: Any, y: float) -> Any:
        return self.m.clamp(x, max=y)

    def clip(self, x: Any, lo: float, hi: float) -> Any:
        return self.m.clamp(x, lo, hi)

    def param(self, value: Any, like: Any) -> Any:
        if isinstance(value, self.m.Tensor):
            return value.to(dtype=like.dtype, device=like.device)
        return self.m.as_tensor(value, dtype=like.dtype, device=like.device)


class JaxBrdfOps(BrdfOps):
    name = "jax"


BACKENDS = ("numpy", "torch", "jax")
"""The array libraries :func:`namespace` supplies."""


@lru_cache(maxsize=None)
def namespace(backend: str) -> BrdfOps:
    """The operations of ``backend`` (one of :data:`BACKENDS`), importing its library."""
    if backend == "numpy":
        import numpy

        return BrdfOps(numpy)
    if backend == "torch":
        import torch

        return TorchBrdfOps(torch)
    if backend == "jax":
        import jax.numpy as jnp

        return JaxBrdfOps(jnp)
    raise PGCConfigError(f"unknown BRDF backend '{backend}'; use one of: {', '.join(BACKENDS)}")
