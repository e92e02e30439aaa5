"""The C++/OpenMP frame kernel ``xpbd.cpp``, built and loaded through :mod:`pgc.native`.

Build ahead of time with ``python -m pgc_native.xpbd.library``; otherwise the first simulation builds it
(a few seconds) into the kernel cache.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path

from pgc import native

SOURCE = Path(__file__).with_name("xpbd.cpp")
FLAGS = (*native.DEFAULT_FLAGS, "-fno-math-errno", "-fno-trapping-math", "-ffp-contract=off", "-fno-exceptions")
"""``-fno-math-errno`` lets ``sqrt`` compile to one instruction and ``-fno-trapping-math`` lets the vectoriser
evaluate both sides of a select; IEEE results are unchanged. ``-ffp-contract=off``: no fused multiply-adds,
so the baseline and the AVX-512 builds in the library give the same bytes."""


def build(force: bool = False) -> Path:
    """Compile the kernel if needed; returns the library path. Raises NativeLibraryUnavailable on failure."""
    return native.build(SOURCE, FLAGS, force=force)


@lru_cache(maxsize=1)
def load() -> ctypes.CDLL:
    """The loaded kernel library (built on first use), with its argument types set."""
    lib = native.load(SOURCE, FLAGS)
    p, i32, i64 = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64
    for suffix in ("f32", "f64"):
        fn = getattr(lib, f"pgc_xpbd_frame_{suffix}")
        fn.argtypes = [i64] * 6 + [i32] * 4 + [p, i32, i32] + [p] * 22
        fn.restype = None
    lib.pgc_xpbd_avx512.argtypes, lib.pgc_xpbd_avx512.restype = [], i32
    return lib


def avx512() -> bool:
    """Whether the kernel runs its AVX-512 build on this CPU (when ``simd`` is on)."""
    return bool(load().pgc_xpbd_avx512())


if __name__ == "__main__":
    print(build())
