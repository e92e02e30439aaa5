"""Build (once, cached) and load the C++/OpenMP compositing kernel ``rasterize.cpp`` through ctypes.

The library is compiled with the system C++ compiler into ``$PGC_CACHE_DIR/kernels`` (default
``~/.cache/pgc/kernels``), keyed by a hash of the source and flags, atomically (temp file + rename).
Build ahead of time with ``python -m pgc_torch.splat.kernel``. Plain C ABI, no torch headers: building takes
about a second.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

SOURCE = Path(__file__).with_name("rasterize.cpp")
FLAGS = ["-O3", "-fopenmp", "-fPIC", "-shared", "-std=c++17"]


class KernelUnavailable(RuntimeError):
    """The compiled kernel cannot be built or loaded (no compiler, no OpenMP, ...)."""


def cache_dir() -> Path:
    root = os.environ.get("PGC_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "pgc")
    return Path(root) / "kernels"


def library_path() -> Path:
    digest = hashlib.sha256(SOURCE.read_bytes() + " ".join(FLAGS).encode()).hexdigest()[:16]
    return cache_dir() / f"pgc_splat_{digest}.so"


def build(force: bool = False) -> Path:
    """Compile the kernel if needed; returns the library path. Raises KernelUnavailable on failure."""
    target = library_path()
    if target.exists() and not force:
        return target
    compiler = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++")
    if compiler is None:
        raise KernelUnavailable("no C++ compiler found (install g++ or set CXX)")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        try:
            res = subprocess.run([compiler, *FLAGS, str(SOURCE), "-o", tmp], capture_output=True, text=True)
        except OSError as exc:
            raise KernelUnavailable(f"cannot run the C++ compiler '{compiler}': {exc}") from exc
        if res.returncode != 0:
            raise KernelUnavailable(f"compiling {SOURCE.name} failed:\n{res.stderr[-2000:]}")
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return target


@lru_cache(maxsize=1)
def load() -> ctypes.CDLL:
    """The loaded kernel library (built on first use)."""
    try:
        lib = ctypes.CDLL(str(build()))
    except OSError as exc:
        raise KernelUnavailable(f"loading the splat kernel failed: {exc}") from exc
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
    try:
        load()
    except KernelUnavailable:
        return False
    return True


if __name__ == "__main__":
    print(build(force=False))
