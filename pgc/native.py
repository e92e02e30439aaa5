"""Compiled C++ kernels: build a single source file into a cached shared library and load it through ctypes.

Backends with compiled paths (the fused splat kernel, the native XPBD) share this one build rule: the system
C++ compiler (``$CXX``, else ``g++`` / ``c++``) compiles the source with the given flags into
``$PGC_CACHE_DIR/kernels`` (default ``~/.cache/pgc/kernels``), named by a hash of the source and flags, written
atomically (temp file + rename) so concurrent processes never load a half-written library. Plain C ABI: no
Python or torch headers, so a build takes a second or two.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Callable, Sequence

from pgc.errors import PGCPluginError

DEFAULT_FLAGS = ("-O3", "-fopenmp", "-fPIC", "-shared", "-std=c++17")


class NativeLibraryUnavailable(PGCPluginError):
    """A compiled kernel cannot be built or loaded (no compiler, no OpenMP, a compile error, ...); the set-up
    installs g++ (Debian), so on a supported machine this names a broken toolchain."""


def cache_dir() -> Path:
    """Folder of the built libraries: ``$PGC_CACHE_DIR/kernels`` (default ``~/.cache/pgc/kernels``)."""
    from pgc.user_cache import user_cache_dir

    return user_cache_dir() / "kernels"


def library_path(source: Path, flags: Sequence[str] = DEFAULT_FLAGS) -> Path:
    """Where the library built from ``source`` with ``flags`` lives (a hash of both names it)."""
    digest = hashlib.sha256(Path(source).read_bytes() + " ".join(flags).encode()).hexdigest()[:16]
    return cache_dir() / f"{Path(source).stem}_{digest}.so"


def build(source: Path, flags: Sequence[str] = DEFAULT_FLAGS, force: bool = False) -> Path:
    """Compile ``source`` if its library is not cached yet; returns the library path.

    Raises :class:`NativeLibraryUnavailable` naming the reason (no compiler, compiler output) on failure.
    """
    target = library_path(source, flags)
    if target.exists() and not force:
        return target
    compiler = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++")
    if compiler is None:
        raise NativeLibraryUnavailable("no C++ compiler found: install g++ (apt-get install g++; scripts/setup.sh does) "
                                "or point CXX at one")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        try:
            res = subprocess.run([compiler, *flags, str(source), "-o", tmp], capture_output=True, text=True)
        except OSError as exc:
            raise NativeLibraryUnavailable(f"cannot run the C++ compiler '{compiler}': {exc}") from exc
        if res.returncode != 0:
            raise NativeLibraryUnavailable(f"compiling {Path(source).name} failed:\n{res.stderr[-2000:]}")
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return target


def load(source: Path, flags: Sequence[str] = DEFAULT_FLAGS) -> ctypes.CDLL:
    """The library of ``source`` (built on first use), loaded; callers set ``argtypes`` and cache the result."""
    try:
        return ctypes.CDLL(str(build(source, flags)))
    except OSError as exc:
        raise NativeLibraryUnavailable(f"loading {Path(source).name}'s library failed: {exc}") from exc


def loads(loader: Callable[[], object]) -> bool:
    """Whether ``loader()`` (a kernel module's cached ``load``) builds and loads its library here."""
    try:
        loader()
    except NativeLibraryUnavailable:
        return False
    return True
