"""The ``pgc`` command line. Each subcommand lives in ``pgc/commands/<name>.py``.

Importing this module (and ``pgc --help``) stays light: no torch, jax, mitsuba, open3d or pycolmap.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import signal
import sys
import threading
import traceback
from typing import Any

from pgc.errors import PGCError

COMMANDS = ("plugins", "config", "synth", "calibrate", "reconstruct", "body", "animate", "render", "eval", "bench", "demo",
            "export", "info", "report", "sweep")

EPILOG = """\
typical session:
  pgc plugins                      what is installed, and what is missing
  pgc demo --preset tiny           synthetic capture -> asset -> novel poses -> metrics, in minutes
  pgc synth OUT --preset default   a synthetic capture with ground truth
  pgc reconstruct OUT --out ASSET  mesh, Gaussians, albedo, material
  pgc config show                  the resolved configuration with every default
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pgc", description="PGC: physics-based Gaussian cloth from a single pose.", epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"pgc {_version()}")
    parser.add_argument("--debug", action="store_true", help="on an error, print the Python traceback too")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"pgc.commands.{name}_cmd")
        module.add_parser(sub)
    return parser


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pgc")
    except PackageNotFoundError:
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    """Run one command. Exit codes: 0 done, 2 a user error (one ``pgc COMMAND: error:`` line naming the file,
    the field and the fix; also for OS errors such as permissions), 1 an unexpected error (one line naming
    the exception; ``--debug`` prints the traceback), 130 interrupted (SIGINT or SIGTERM)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    _SIGNALLED.clear()
    previous = signal.signal(signal.SIGTERM, _terminate) if _main_thread() else None
    previous_int = signal.signal(signal.SIGINT, _terminate) if _main_thread() else None
    try:
        return int(args.func(args) or 0)
    except PGCError as exc:
        return _fail(args, str(exc), 2)
    except KeyboardInterrupt:
        print(f"pgc {args.command}: interrupted; completed stages are kept and a rerun resumes", file=sys.stderr)
        return _interrupted_exit(argv)
    except OSError as exc:
        return _fail(args, os_error_message(exc), 2)
    except Exception as exc:
        if _SIGNALLED or _interrupted(exc):  # Ctrl-C or SIGTERM arrived, e.g. while a C extension imported
            print(f"pgc {args.command}: interrupted; completed stages are kept and a rerun resumes", file=sys.stderr)
            return _interrupted_exit(argv)
        return _fail(args, f"unexpected {type(exc).__name__}: {exc}; this is a bug or an input PGC does not "
                           "check yet: rerun with 'pgc --debug ...' for the traceback and report it", 1)
    finally:
        _close_bars()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        if previous_int is not None:
            signal.signal(signal.SIGINT, previous_int)


def _interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` was caused by an interruption (an extension module's import fails with ImportError when a
    signal's KeyboardInterrupt arrives during its initialisation)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


DISK_FIXES = {errno.ENOSPC: "the disk is full: free space on it or write to another disk",
              errno.EDQUOT: "the disk quota is used up: free space or write to another disk",
              errno.EROFS: "the file system is read-only: give a path on a writable disk",
              errno.EIO: "the disk reported an I/O error: check it, or write to another disk"}
"""What fixes the OS errors that concern the disk rather than the path (by ``errno``)."""


def os_error_message(exc: OSError) -> str:
    """One line for an OS error: the path (the writers attach their output's path to errors that name no file,
    :func:`pgc.checks.naming_output`), the system's reason and what usually fixes it."""
    reason = exc.strerror or str(exc)
    fix = DISK_FIXES.get(exc.errno) or {
        PermissionError: "check the permissions, or give a folder you can write",
        NotADirectoryError: "a part of the path is a file: give a folder path",
        IsADirectoryError: "it is a folder: give a file path",
        FileNotFoundError: "check the path",
        FileExistsError: "remove it or give another path"}.get(type(exc), "check the path and the disk")
    return reason + "; " + fix if exc.filename is None else f"{exc.filename}: {reason}; {fix}"


def _fail(args: argparse.Namespace, message: str, code: int) -> int:
    if getattr(args, "debug", False):
        traceback.print_exc()
    print(f"pgc {args.command}: error: {message}", file=sys.stderr)
    return code


_SIGNALLED: list[int] = []
"""Signals received by the running command (an interruption may surface as another exception: an extension
module's import fails with ImportError when the signal lands during its initialisation)."""


def _terminate(signum: int, frame: Any) -> None:
    """SIGINT and SIGTERM unwind like Ctrl-C: temporary files are removed, the folder lock released.

    A signal that lands while a module is being imported is delivered again 50 ms later: an extension whose
    initialisation runs Python code (drjit's nanobind enums) aborts the process when an exception is raised
    inside it."""
    if _importing(frame):
        timer = threading.Timer(0.05, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    _SIGNALLED.append(signum)
    raise KeyboardInterrupt


def _importing(frame: Any) -> bool:
    """Whether the interrupted code runs inside an import (a frame of importlib's bootstrap on the stack)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _close_bars() -> None:
    """Close the progress bars of stages a failed or interrupted command left open."""
    if "pgc.progress" in sys.modules:
        sys.modules["pgc.progress"].ProgressPrinter.close_all()


def _interrupted_exit(argv: list[str] | None) -> int:
    """130. As the program (``argv`` None: the ``pgc`` script), exit at once after closing the progress bars
    and flushing: interpreter finalisation after an extension was interrupted mid-work (Mitsuba's threads) can
    abort the process."""
    if argv is None:
        _close_bars()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)
    return 130


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


if __name__ == "__main__":
    sys.exit(main())
