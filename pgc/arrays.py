"""The array-operations layer: maths written once, run by numpy, torch and JAX.

The BRDF maths (:mod:`pgc.brdfs.maths`), the XPBD maths (:mod:`pgc.sim.xpbd`) and the splat maths take an
:class:`ArrayOps` and compute through it. ``ops.xp`` is the library's numpy-like namespace for the calls
every library spells alike (``abs``, ``arange``, ``zeros_like``, ``sum``/``mean`` as methods, ``einsum``,
indexing, ``@``); the methods of :class:`ArrayOps` are the calls that differ (``clamp`` against ``clip``,
``dim`` against ``axis``, ``index_add`` on immutable JAX arrays, ``fori_loop``, devices).

Conventions: a vector or colour is an array with a trailing axis of 3 (positions in metres, directions unit,
colours linear RGB); a *scalar field* is one value per leading index; scalars may be Python numbers. Results
are new arrays (JAX arrays are immutable), in the dtype and on the device of the inputs.

:func:`array_ops` gives the cached operations of one library and imports that library on first use (importing
this module imports neither torch nor JAX). A backend with other array types subclasses :class:`ArrayOps`
and overrides what its types spell differently (the Mitsuba backend's Dr.Jit operations, ``pgc_mitsuba.ops``,
hold ``Vector3f`` / ``Color3f`` values instead of a trailing axis).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from pgc.errors import PGCConfigError

LIBRARIES = ("numpy", "torch", "jax")
"""The array libraries :func:`array_ops` supplies."""

LUMINANCE = (0.212671, 0.715160, 0.072169)
"""Linear-sRGB luminance weights (Mitsuba's ``luminance``)."""

PADDINGS = ("zeros", "reflect")
"""Border modes of :meth:`ArrayOps.separable_filter`: zeros outside the image, or the image mirrored about
its edge with the edge pixel repeated (``d c b a | a b c d | d c b a``, scipy's ``reflect``)."""


class ArrayOps:
    """The operations of one array library; this base class is numpy's (``xp`` = the ``numpy`` module)."""

    name = "numpy"

    def __init__(self, xp: Any) -> None:
        self.xp = xp

    # -- element-wise ------------------------------------------------------------------------------------
    def sqrt(self, x: Any) -> Any:
        return self.xp.sqrt(x)

    def exp(self, x: Any) -> Any:
        return self.xp.exp(x)

    def maximum(self, x: Any, y: float) -> Any:
        """Element-wise ``max(x, y)`` with ``y`` a Python number."""
        return self.xp.maximum(x, y)

    def minimum(self, x: Any, y: float) -> Any:
        """Element-wise ``min(x, y)`` with ``y`` a Python number."""
        return self.xp.minimum(x, y)

    def clip(self, x: Any, lo: float, hi: float) -> Any:
        return self.xp.clip(x, lo, hi)

    def where(self, cond: Any, a: Any, b: Any) -> Any:
        return self.xp.where(cond, a, b)

    def sigmoid(self, x: Any) -> Any:
        """The logistic function, overflow-free (numpy: ``(1 + tanh(x / 2)) / 2``)."""
        return 0.5 * (1.0 + self.xp.tanh(0.5 * x))

    def stop_gradient(self, x: Any) -> Any:
        """``x`` as a constant of automatic differentiation (numpy: ``x`` itself)."""
        return x

    # -- the trailing axis of 3 --------------------------------------------------------------------------
    def split(self, v: Any) -> tuple[Any, Any, Any]:
        """Components of a (..., 3) vector."""
        return v[..., 0], v[..., 1], v[..., 2]

    def expand(self, s: Any) -> Any:
        """A scalar field (...,) made broadcastable against vectors (..., 3); Python numbers unchanged."""
        return s if isinstance(s, (int, float)) else s[..., None]

    def norm(self, v: Any) -> Any:
        """Euclidean length of (..., 3) vectors (or any trailing axis) -> (...,)."""
        return self.xp.sqrt((v * v).sum(-1))

    def cross(self, a: Any, b: Any) -> Any:
        """Cross product of (..., 3) vectors."""
        return self.xp.cross(a, b)

    def luminance(self, c: Any) -> Any:
        """Luminance (...,) of linear-sRGB colours (..., 3), weights :data:`LUMINANCE`."""
        return c[..., 0] * LUMINANCE[0] + c[..., 1] * LUMINANCE[1] + c[..., 2] * LUMINANCE[2]

    # -- building arrays ---------------------------------------------------------------------------------
    def stack(self, arrays: Sequence[Any], axis: int = 0) -> Any:
        return self.xp.stack(arrays, axis=axis)

    def concat(self, arrays: Sequence[Any], axis: int = 0) -> Any:
        return self.xp.concatenate(arrays, axis=axis)

    def asarray(self, value: Any, dtype: Any = None, like: Any = None) -> Any:
        """``value`` (number, sequence, numpy or this library's array) as this library's array.

        ``dtype``: a name (``"float32"``) or the library's dtype; default ``like``'s dtype, else the library's
        choice. ``like``: an array whose dtype (and device, for torch) the result takes.
        """
        return self.xp.asarray(value, dtype=self._dtype(dtype, like))

    def param(self, value: Any, like: Any) -> Any:
        """A parameter value (float, 3-list, array) as an array of ``like``'s library, dtype and device."""
        return self.asarray(value, like=like)

    def zeros(self, shape: int | tuple[int, ...], like: Any) -> Any:
        """Zeros of ``shape`` in ``like``'s dtype (and device)."""
        return self.xp.zeros(shape, dtype=like.dtype)

    def to_numpy(self, x: Any) -> np.ndarray:
        """A numpy copy or view of ``x`` (detached from any autodiff graph)."""
        return np.asarray(x)

    def _dtype(self, dtype: Any, like: Any) -> Any:
        if isinstance(dtype, str):
            return getattr(self.xp, dtype)
        if dtype is None and like is not None:
            return like.dtype
        return dtype

    # -- scatter and loops -------------------------------------------------------------------------------
    def index_add(self, a: Any, idx: Any, values: Any) -> Any:
        """A copy of ``a`` with ``values`` added at rows ``idx`` (repeated indices sum)."""
        out = a.copy()
        np.add.at(out, idx, values)
        return out

    def loop(self, n: int, body: Callable[[Any, Any], Any], carry: Any) -> Any:
        """``carry`` after ``carry = body(k, carry)`` for k in range(n) (``lax.fori_loop`` in JAX: traceable)."""
        for k in range(n):
            carry = body(k, carry)
        return carry

    # -- filtering ---------------------------------------------------------------------------------------
    def transpose(self, x: Any, axes: Sequence[int]) -> Any:
        """``x`` with its axes in the order ``axes`` (a view where the library has views)."""
        return self.xp.transpose(x, tuple(axes))

    def separable_filter(self, images: Any, taps: Sequence[float], padding: str = "zeros") -> Any:
        """Correlation of each (H, W) plane of an (N, C, H, W) batch with the 2-D window ``outer(taps, taps)``,
        same size out.

        ``taps``: an odd number of weights (the window is separable: a pass along H, then along W). ``padding``:
        one of :data:`PADDINGS`. The batch is in the layout convolutions take, so torch and JAX filter without
        moving memory: a caller that filters several (H, W, C) images moves their axes once (:meth:`transpose`),
        and torch keeps the memory format it finds (a transposed (H, W, C) image is channels-last) through every
        pass and its gradient.
        """
        from scipy.ndimage import correlate1d

        _check_filter(images, taps, padding)
        mode = "constant" if padding == "zeros" else "reflect"
        w = np.asarray(taps, dtype=images.dtype)
        return correlate1d(correlate1d(images, w, axis=2, mode=mode), w, axis=3, mode=mode)


def _check_filter(images: Any, taps: Sequence[float], padding: str) -> None:
    if padding not in PADDINGS:
        raise PGCConfigError(f"separable_filter: padding '{padding}' is not one of {', '.join(PADDINGS)}")
    if len(images.shape) != 4 or len(taps) % 2 != 1:
        raise PGCConfigError(f"separable_filter: needs an (N, C, H, W) batch of images and an odd number of "
                             f"taps, got shape {tuple(images.shape)} and {len(taps)} taps")


def _reflect_index(n: int, r: int) -> np.ndarray:
    """Row indices of an axis of length ``n`` padded by ``r`` on each side in :data:`PADDINGS`' ``reflect``."""
    return np.pad(np.arange(n), r, mode="symmetric")


class TorchOps(ArrayOps):
    name = "torch"

    def maximum(self, x: Any, y: float) -> Any:
        return self.xp.clamp(x, min=y)

    def minimum(self, x: Any, y: float) -> Any:
        return self.xp.clamp(x, max=y)

    def clip(self, x: Any, lo: float, hi: float) -> Any:
        return self.xp.clamp(x, lo, hi)

    def cross(self, a: Any, b: Any) -> Any:
        return self.xp.linalg.cross(a, b, dim=-1)

    def sigmoid(self, x: Any) -> Any:
        return self.xp.sigmoid(x)

    def stop_gradient(self, x: Any) -> Any:
        return x.detach()

    def stack(self, arrays: Sequence[Any], axis: int = 0) -> Any:
        return self.xp.stack(tuple(arrays), dim=axis)

    def concat(self, arrays: Sequence[Any], axis: int = 0) -> Any:
        return self.xp.cat(tuple(arrays), dim=axis)

    def asarray(self, value: Any, dtype: Any = None, like: Any = None) -> Any:
        dtype = self._dtype(dtype, like)
        device = None if like is None else like.device
        if isinstance(value, self.xp.Tensor):
            return value.to(dtype=dtype, device=device)
        return self.xp.as_tensor(value, dtype=dtype, device=device)

    def zeros(self, shape: int | tuple[int, ...], like: Any) -> Any:
        return self.xp.zeros(shape, dtype=like.dtype, device=like.device)

    def to_numpy(self, x: Any) -> np.ndarray:
        return x.detach().cpu().numpy()

    def index_add(self, a: Any, idx: Any, values: Any) -> Any:
        return a.index_add(0, idx, values)

    def transpose(self, x: Any, axes: Sequence[int]) -> Any:
        return x.permute(*axes)

    def separable_filter(self, images: Any, taps: Sequence[float], padding: str = "zeros") -> Any:
        torch = self.xp
        _check_filter(images, taps, padding)
        k, (_, c, h, w) = len(taps), images.shape
        r = k // 2
        g = torch.as_tensor(np.asarray(taps, dtype=np.float64), device=images.device).to(images.dtype)
        x, p = images, r
        if padding == "reflect":
            rows = torch.as_tensor(_reflect_index(h, r), device=images.device)
            cols = torch.as_tensor(_reflect_index(w, r), device=images.device)
            x, p = x[:, :, rows][:, :, :, cols], 0
        conv = torch.nn.functional.conv2d
        x = conv(x, g.view(1, 1, k, 1).expand(c, 1, k, 1).contiguous(), padding=(p, 0), groups=c)
        return conv(x, g.view(1, 1, 1, k).expand(c, 1, 1, k).contiguous(), padding=(0, p), groups=c)


class JaxOps(ArrayOps):
    name = "jax"

    def sigmoid(self, x: Any) -> Any:
        import jax

        return jax.nn.sigmoid(x)

    def stop_gradient(self, x: Any) -> Any:
        import jax

        return jax.lax.stop_gradient(x)

    def index_add(self, a: Any, idx: Any, values: Any) -> Any:
        return a.at[idx].add(values)

    def loop(self, n: int, body: Callable[[Any, Any], Any], carry: Any) -> Any:
        import jax

        return jax.lax.fori_loop(0, n, body, carry)

    def separable_filter(self, images: Any, taps: Sequence[float], padding: str = "zeros") -> Any:
        import jax

        jnp = self.xp
        _check_filter(images, taps, padding)
        k, (_, c, h, w) = len(taps), images.shape
        r = k // 2
        g = jnp.asarray(np.asarray(taps, dtype=np.float64), dtype=images.dtype)
        x, p = images, r
        if padding == "reflect":
            x, p = x[:, :, _reflect_index(h, r)][:, :, :, _reflect_index(w, r)], 0
        dn = ("NCHW", "OIHW", "NCHW")
        for kernel, pad in ((g.reshape(1, 1, k, 1), ((p, p), (0, 0))), (g.reshape(1, 1, 1, k), ((0, 0), (p, p)))):
            x = jax.lax.conv_general_dilated(x, jnp.tile(kernel, (c, 1, 1, 1)), (1, 1), pad,
                                             dimension_numbers=dn, feature_group_count=c)
        return x


@lru_cache(maxsize=None)
def array_ops(library: str) -> ArrayOps:
    """The operations of ``library`` (one of :data:`LIBRARIES`), importing it on first use; one object per
    library (hashable: JAX may take it as a static argument)."""
    if library == "numpy":
        return ArrayOps(np)
    if library == "torch":
        import torch

        return TorchOps(torch)
    if library == "jax":
        import jax.numpy as jnp

        return JaxOps(jnp)
    raise PGCConfigError(f"unknown array library '{library}'; use one of: {', '.join(LIBRARIES)}")


def array_ops_for(x: Any) -> ArrayOps:
    """The operations of the library that holds array ``x`` (a numpy, torch or JAX array)."""
    module = type(x).__module__.split(".")[0]
    if module in ("jax", "jaxlib"):
        return array_ops("jax")
    if module in LIBRARIES:
        return array_ops(module)
    raise PGCConfigError(f"no array operations for {type(x).__module__}.{type(x).__name__}; "
                         f"arrays of {', '.join(LIBRARIES)} are supported")


def float_operands(x: Any) -> tuple[ArrayOps, Any]:
    """``x`` with the operations of its library: a torch or JAX array as it is (dtype, device and autodiff graph
    kept); anything else (numpy arrays, sequences, numbers) as a float64 numpy array."""
    if type(x).__module__.split(".")[0] in ("torch", "jax", "jaxlib"):
        return array_ops_for(x), x
    return array_ops("numpy"), np.asarray(x, dtype=np.float64)
