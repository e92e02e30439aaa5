"""The fused splat path: one compiled call renders world Gaussians, one computes the gradients of all five inputs.

``fused.cpp`` does projection (float64 per Gaussian), SH colour, culling, opacity-aware binning, depth order and
compositing (float32 SIMD across 8-pixel chunks of a row, AVX2 intrinsics where the CPU has AVX2 and FMA), and
their backward; :class:`FusedRasterize` wraps it as a single ``torch.autograd.Function``, so a fit step builds no
graph of per-Gaussian torch ops. Built through :mod:`pgc.native` with AVX2/FMA code generation when this CPU
reports both (``/proc/cpuinfo``), else the default flags (always with ``-fno-trapping-math``, which lets GCC
vectorise the generic pixel loops). Build ahead of time with ``python -m pgc_torch.splat.fused``."""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch

from pgc import native
from pgc.native import KernelUnavailable
from pgc.types import Camera

SOURCE = Path(__file__).with_name("fused.cpp")
SIMD_FLAGS = ("-mavx2", "-mfma")
VECTOR_FLAGS = ("-fno-trapping-math",)
"""Lets GCC if-convert the pixel loops (select instead of branch); values are unchanged (no -ffast-math)."""
__all__ = ["FusedRasterize", "KernelUnavailable", "available", "build", "flags", "load", "machine_peaks",
           "render_stats"]


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
    """Compile the fused kernel if needed; returns the library path. Raises KernelUnavailable on failure."""
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


def camera_vector(camera: Camera, near: float) -> torch.Tensor:
    """The 21 doubles the kernel reads: R (row-major), t, K00, K01, K02, K11, K12, camera centre, near."""
    K = np.asarray(camera.K, np.float64)
    values = np.concatenate([np.asarray(camera.R, np.float64).ravel(), np.asarray(camera.t, np.float64).ravel(),
                             [K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]],
                             np.asarray(camera.center, np.float64).ravel(), [near]])
    return torch.from_numpy(values)


class _Workspace:
    """Owner of the kernel's forward state (order, tile lists, final transmittance); freed with the object."""

    def __init__(self, handle: int, suffix: str) -> None:
        self.handle, self.suffix = handle, suffix

    def __del__(self) -> None:
        getattr(load(), f"pgc_fused_free_{self.suffix}")(self.handle)


def _forward(means, rotmats, scales, opacities, sh, camera: Camera, background: torch.Tensor, count: int,
             near: float, tile: int, threads: int):
    dtype = means.dtype
    suffix = "f64" if dtype == torch.float64 else "f32"
    inputs = [x.detach().to(dtype).contiguous() for x in (means, rotmats, scales, opacities, sh)]
    cam = camera_vector(camera, near)
    bg = background.to(dtype).contiguous()
    h, w = camera.height, camera.width
    color = torch.empty(h, w, 3, dtype=dtype)
    alpha = torch.empty(h, w, dtype=dtype)
    dsum = torch.empty(h, w, dtype=dtype)
    stats = torch.zeros(3, dtype=torch.int64)
    n, k = inputs[0].shape[0], inputs[4].shape[1]
    handle = getattr(load(), f"pgc_fused_forward_{suffix}")(
        *(x.data_ptr() for x in inputs), n, k, count, cam.data_ptr(), h, w, tile, bg.data_ptr(), color.data_ptr(),
        alpha.data_ptr(), dsum.data_ptr(), stats.data_ptr(), threads)
    return inputs, cam, bg, color, alpha, dsum, stats, _Workspace(handle, suffix)


class FusedRasterize(torch.autograd.Function):
    """World Gaussians -> (colour (H, W, 3), alpha (H, W), weighted depth sum (H, W)) in one compiled call.

    Differentiable w.r.t. means (N, 3), rotmats (N, 3, 3), scales (N, 3), opacities (N,) and sh (N, K, 3);
    float32 or float64 (every tensor in the dtype of ``means``). ``count`` = SH coefficients used.
    """

    @staticmethod
    def forward(ctx, means, rotmats, scales, opacities, sh, camera: Camera, background: torch.Tensor, count: int,
                near: float, tile: int, threads: int):
        inputs, cam, bg, color, alpha, dsum, _, ws = _forward(means, rotmats, scales, opacities, sh, camera,
                                                              background, count, near, tile, threads)
        ctx.save_for_backward(*inputs)
        ctx.state = (cam, bg, ws, count, threads)
        return color, alpha, dsum

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, g_color, g_alpha, g_dsum):
        inputs = ctx.saved_tensors
        cam, bg, ws, count, threads = ctx.state
        dtype = inputs[0].dtype
        grads = [torch.empty_like(x) for x in inputs]
        g = [torch.zeros_like(ref) if x is None else x.to(dtype).contiguous()
             for x, ref in ((g_color, bg), (g_alpha, bg[..., 0]), (g_dsum, bg[..., 0]))]
        n, k = inputs[0].shape[0], inputs[4].shape[1]
        getattr(load(), f"pgc_fused_backward_{ws.suffix}")(
            ws.handle, *(x.data_ptr() for x in inputs), n, k, count, cam.data_ptr(), bg.data_ptr(),
            *(x.data_ptr() for x in g), *(x.data_ptr() for x in grads), threads)
        return (*grads, None, None, None, None, None, None)


def render_stats(means, rotmats, scales, opacities, sh, camera: Camera, count: int, near: float = 0.01,
                 tile: int = 16, threads: int = 1) -> dict[str, int]:
    """Work counts of one fused render: visible Gaussians, tile entries, pixel-Gaussian pairs inside the
    footprint boxes (the forward's evaluations, before early termination)."""
    bg = torch.zeros(camera.height, camera.width, 3, dtype=means.dtype)
    with torch.no_grad():
        stats = _forward(means, rotmats, scales, opacities, sh, camera, bg, count, near, tile, threads)[6]
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
