"""The C++/OpenMP compositing kernel ``rasterize.cpp``, built and loaded through :mod:`pgc.native`.

Build ahead of time with ``python -m pgc_torch.splat.kernel`` (the set-up does); otherwise the first render
builds it (about a second) into the kernel cache.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

from pgc import native
from pgc.native import KernelUnavailable

SOURCE = Path(__file__).with_name("rasterize.cpp")
__all__ = ["KernelUnavailable", "available", "build", "load"]


def build(force: bool = False) -> Path:
    """Compile the kernel if needed; returns the library path. Raises KernelUnavailable on failure."""
    return native.build(SOURCE, force=force)


@lru_cache(maxsize=1)
def load() -> ctypes.CDLL:
    """The loaded kernel library (built on first use), with its argument types set."""
    lib = native.load(SOURCE)
    p, i32, i64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_int64
    for suffix in ("f32", "f64"):
        fwd = getattr(lib, f"pgc_splat_forward_{suffix}")
        fwd.argtypes = [p] * 8 + [i32, i32, i32] + [p] * 5 + [i32]
        fwd.restype = None
        bwd = getattr(lib, f"pgc_splat_backward_{suffix}")
        bwd.argtypes = [p] * 8 + [i32, i32, i32, i64] + [p] * 7 + [i32]
        bwd.restype = None
    return lib


def available() -> bool:
    """Whether the kernel builds and loads here."""
    return native.loads(load)


if __name__ == "__main__":
    print(build(force=False))
