"""The fused splat kernel on numpy arrays: one compiled call renders world Gaussians, one gives the gradients of
all five inputs. The array-library wrappers (a ``torch.autograd.Function``, a ``jax.custom_vjp``) sit on this.

``fused.cpp`` does projection (float64 per Gaussian), SH colour, culling, opacity-aware binning, depth order and
compositing (float32 SIMD across 8-pixel chunks of a row, AVX2 intrinsics where the CPU has AVX2 and FMA), and
their backward. Built through :mod:`pgc.native` with AVX2/FMA code generation when this CPU reports both
(``/proc/cpuinfo``), else the default flags (always with ``-fno-trapping-math``, which lets GCC vectorise the
generic pixel loops). Build ahead of time with ``python -m pgc.splats.fused``.

Conventions: arrays are C-contiguous, all five inputs of one dtype (float32 or float64): means (N, 3) metres,
rotmats (N, 3, 3) (columns = the Gaussian's axes), scales (N, 3) metres (standard deviations), opacities (N,),
sh (N, K, 3); the first ``count`` SH coefficients are used. Outputs: colour (H, W, 3) linear RGB composited over
the background, alpha (H, W), and the alpha-weighted depth sum (H, W) (depth = sum / alpha).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from pgc import native
from pgc.checks import require_finite
from pgc.native import NativeLibraryUnavailable
from pgc.types import Camera

SOURCE = Path(__file__).with_name("fused.cpp")
SIMD_FLAGS = ("-mavx2", "-mfma")
VECTOR_FLAGS = ("-fno-trapping-math",)
"""Lets GCC if-convert the pixel loops (select instead of branch); values are unchanged (no -ffast-math)."""
DEFAULT_TILE = 16
"""Tile edge (pixels) of the kernel's binning; the image does not depend on it."""
__all__ = ["DEFAULT_TILE", "NativeLibraryUnavailable", "Workspace", "available", "backward", "build", "camera_vector", "flags",
           "forward", "load", "machine_peaks", "render_path", "render_stats"]


def cpu_flags() -> set[str]:
    """The instruction-set flags this CPU reports (empty where ``/proc/cpuinfo`` is unreadable)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


@lru_cache(maxsize=1)
def flags() -> tuple[str, ...]:
    """Compiler flags: the defaults and ``-fno-trapping-math``, plus ``-mavx2 -mfma`` when the CPU has both."""
    simd = SIMD_FLAGS if {"avx2", "fma"} <= cpu_flags() else ()
    return (*native.DEFAULT_FLAGS, *VECTOR_FLAGS, *simd)


def build(force: bool = False) -> Path:
    """Compile the fused kernel if needed; returns the library path. Raises NativeLibraryUnavailable on failure."""
    return native.build(SOURCE, flags(), force=force)


@lru_cache(maxsize=1)
def load() -> ctypes.CDLL:
    """The loaded fused library (built on first use), with its argument types set."""
    lib = native.load(SOURCE, flags())
    p, i32, i64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_int64
    for suffix in ("f32", "f64"):
        fwd = getattr(lib, f"pgc_fused_forward_{suffix}")
        fwd.argtypes = [p] * 5 + [i64, i32, i32, p, i32, i32, i32] + [p] * 5 + [i32]
        fwd.restype = p
        bwd = getattr(lib, f"pgc_fused_backward_{suffix}")
        bwd.argtypes = [p] * 6 + [i64, i32, i32] + [p] * 10 + [i32]
        bwd.restype = None
        free = getattr(lib, f"pgc_fused_free_{suffix}")
        free.argtypes = [p]
        free.restype = None
    for name in ("pgc_fused_peak_fma", "pgc_fused_peak_exp"):
        getattr(lib, name).argtypes = [i64, i32]
        getattr(lib, name).restype = ctypes.c_double
    return lib


def available() -> bool:
    """Whether the fused kernel builds and loads here."""
    return native.loads(load)


def render_path(choice: str, fallback: str, host: bool = True) -> str:
    """The render path a renderer's ``compositor`` option names: "auto" is "fused" when the arrays live on the
    host (``host``) and the kernel builds here, else ``fallback``; "fused" loads the kernel (raising
    :class:`NativeLibraryUnavailable` with the reason); any other choice is returned as it is."""
    if choice == "auto":
        return "fused" if host and available() else fallback
    if choice == "fused":
        load()
    return choice


def camera_vector(camera: Camera, near: float) -> np.ndarray:
    """The 21 doubles the kernel reads: R (row-major), t, K00, K01, K02, K11, K12, camera centre, near."""
    K = np.asarray(camera.K, np.float64)
    return np.concatenate([np.asarray(camera.R, np.float64).ravel(), np.asarray(camera.t, np.float64).ravel(),
                           [K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]],
                           np.asarray(camera.center, np.float64).ravel(), [near]])


def _suffix(dtype: np.dtype) -> str:
    if dtype == np.float64:
        return "f64"
    if dtype == np.float32:
        return "f32"
    raise TypeError(f"the fused splat kernel takes float32 or float64 arrays, got {dtype}")


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


class Workspace:
    """Owner of one forward's state (depth order, tile lists, final transmittance) that its backward reads;
    freed with the object."""

    def __init__(self, handle: int, suffix: str, height: int, width: int) -> None:
        self.handle, self.suffix, self.height, self.width = handle, suffix, height, width

    def __del__(self) -> None:
        getattr(load(), f"pgc_fused_free_{self.suffix}")(self.handle)


@dataclass
class Rendered:
    """One forward's images, work counts (visible Gaussians, tile entries, box pairs) and workspace."""

    color: np.ndarray
    alpha: np.ndarray
    depth_sum: np.ndarray
    stats: np.ndarray
    workspace: Workspace

    @property
    def depth(self) -> np.ndarray:
        """Expected depth (H, W), metres: the weighted depth sum over alpha, 0 where alpha is 0."""
        has = self.alpha > 0
        return np.where(has, self.depth_sum / np.where(has, self.alpha, 1.0), 0.0)


INPUT_NAMES = ("means", "rotmats", "scales", "opacities", "sh")


def _inputs(arrays: Sequence[np.ndarray]) -> list[np.ndarray]:
    dtype = np.asarray(arrays[0]).dtype
    out = [np.ascontiguousarray(a, dtype) for a in arrays]
    _suffix(out[0].dtype)
    return out


def forward(inputs: Sequence[np.ndarray], camera_vec: np.ndarray, background: np.ndarray, height: int, width: int,
            count: int, tile: int = DEFAULT_TILE, threads: int = 1, check_finite: bool = True) -> Rendered:
    """Render the five ``inputs`` (see the module's conventions) seen by the camera of ``camera_vec``
    (:func:`camera_vector`) over ``background`` (H, W, 3, the inputs' dtype).

    ``check_finite``: refuse NaN/Inf inputs (the kernel would drop those Gaussians silently); one pass over the
    arrays, about 1-5 % of a forward. Callers whose inputs were checked already (a fit's own parameters) may
    skip it."""
    arrs = _inputs(inputs)
    if check_finite:
        for name, a in zip(INPUT_NAMES, arrs):
            require_finite("fused splat kernel", name, a)
        require_finite("fused splat kernel", "background", background)
    dtype, suffix = arrs[0].dtype, _suffix(arrs[0].dtype)
    cam = np.ascontiguousarray(camera_vec, np.float64)
    bg = np.ascontiguousarray(np.broadcast_to(background, (height, width, 3)), dtype)
    color = np.empty((height, width, 3), dtype)
    alpha = np.empty((height, width), dtype)
    dsum = np.empty((height, width), dtype)
    stats = np.zeros(3, np.int64)
    n, k = arrs[0].shape[0], arrs[4].shape[1]
    handle = getattr(load(), f"pgc_fused_forward_{suffix}")(
        *(_ptr(a) for a in arrs), n, k, count, _ptr(cam), height, width, tile, _ptr(bg), _ptr(color), _ptr(alpha),
        _ptr(dsum), _ptr(stats), threads)
    return Rendered(color, alpha, dsum, stats, Workspace(handle, suffix, height, width))


def backward(workspace: Workspace, inputs: Sequence[np.ndarray], camera_vec: np.ndarray, background: np.ndarray,
             grad_color: np.ndarray | None, grad_alpha: np.ndarray | None, grad_depth_sum: np.ndarray | None,
             count: int, threads: int = 1) -> list[np.ndarray]:
    """Gradients of the five ``inputs`` given the output gradients (None = zero) of the forward that made
    ``workspace`` from the same inputs, camera and background."""
    arrs = _inputs(inputs)
    dtype = arrs[0].dtype
    if _suffix(dtype) != workspace.suffix:
        raise TypeError(f"backward in {dtype} of a {workspace.suffix} forward")
    cam = np.ascontiguousarray(camera_vec, np.float64)
    h, w = workspace.height, workspace.width
    bg = np.ascontiguousarray(np.broadcast_to(background, (h, w, 3)), dtype)
    g = [np.zeros(shape, dtype) if x is None else np.ascontiguousarray(x, dtype)
         for x, shape in ((grad_color, (h, w, 3)), (grad_alpha, (h, w)), (grad_depth_sum, (h, w)))]
    grads = [np.empty_like(a) for a in arrs]
    n, k = arrs[0].shape[0], arrs[4].shape[1]
    getattr(load(), f"pgc_fused_backward_{workspace.suffix}")(
        workspace.handle, *(_ptr(a) for a in arrs), n, k, count, _ptr(cam), _ptr(bg), *(_ptr(x) for x in g),
        *(_ptr(x) for x in grads), threads)
    return grads


def render_stats(inputs: Sequence[np.ndarray], camera: Camera, count: int, near: float = 0.01, tile: int = DEFAULT_TILE,
                 threads: int = 1) -> dict[str, int]:
    """Work counts of one fused render: visible Gaussians, tile entries, pixel-Gaussian pairs inside the
    footprint boxes (the forward's evaluations, before early termination)."""
    dtype = np.asarray(inputs[0]).dtype
    bg = np.zeros((camera.height, camera.width, 3), dtype)
    stats = forward(inputs, camera_vector(camera, near), bg, camera.height, camera.width, count, tile, threads).stats
    return {"visible": int(stats[0]), "entries": int(stats[1]), "pairs": int(stats[2])}


def machine_peaks(threads: int = 1, seconds: float = 0.2) -> dict[str, float]:
    """This CPU's float FMA throughput (FLOP/s, an FMA = 2) and the kernel's exp throughput (evaluations/s) on
    ``threads`` threads, measured by compiled loops built with the kernel's flags (about ``seconds`` of CPU
    time each), per second of each thread's own CPU time (robust on a shared machine)."""
    lib = load()
    out = {}
    for key, name, per_iter in (("fma_flops", "pgc_fused_peak_fma", 256.0), ("exp_per_s", "pgc_fused_peak_exp", 256.0)):
        fn = getattr(lib, name)
        iters = 100_000
        while per_iter * iters * threads / fn(iters, threads) < seconds:  # grow until a call takes ``seconds``
            iters *= 2
        out[key] = max(fn(iters, threads) for _ in range(3))
    return out


if __name__ == "__main__":
    print(build(force=False))
