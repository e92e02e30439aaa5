"""Shared pieces of the run commands: the --config/--quiet options, the registry + progress display (with
the config's ``[plugins] block`` applied), output-path checks and the output folder lock."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
from pathlib import Path
from typing import Any, Iterator

from pgc.checks import naming_output
from pgc.errors import PGCConfigError, PGCDataError


def add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE", help="run configuration TOML (default: built-in defaults; "
                                                     "see 'pgc config show')")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def config_block(path: str | os.PathLike | None) -> list[str]:
    """The ``[plugins] block`` list of a config file (empty without a file), checked."""
    if path is None:
        return []
    from pgc.config import load_toml

    plugins = load_toml(path).get("plugins", {})
    block = plugins.get("block", []) if isinstance(plugins, dict) else None
    if not isinstance(block, list) or not all(isinstance(b, str) for b in block):
        raise PGCConfigError(f"{path}: [plugins] block must be a list of names (entry points or 'role:name')")
    return block


def discover(args: argparse.Namespace):
    """The registry of installed plugins, with the blocks of ``--config`` (and PGC_BLOCK_PLUGINS) applied."""
    from pgc.registry import Registry

    return Registry.discover(block=config_block(getattr(args, "config", None)))


def reporter_for(args: argparse.Namespace):
    """A registry with the progress display attached (unless --quiet) and a Reporter on its hooks."""
    from pgc.events import Reporter
    from pgc.progress import ProgressPrinter

    registry = discover(args)
    if not getattr(args, "quiet", False):
        registry.plugin_manager.register(ProgressPrinter(), name="progress")
    return registry, Reporter(registry.hook)


def load_config(args: argparse.Namespace, registry: Any):
    """The run configuration of ``--config`` (the defaults without one), validated, with every chosen
    implementation checked (:meth:`pgc.config.RunConfig.check_implementations`) before any work."""
    from pgc import config

    cfg = config.load(getattr(args, "config", None), registry)
    cfg.check_implementations()
    return cfg


def emit(args: argparse.Namespace, result: dict[str, Any], text: str) -> None:
    from pgc.io.atomic import finite_or_none

    print(json.dumps(finite_or_none(result), indent=2, default=str) if getattr(args, "json", False) else text)


def check_out_folder(path: str | os.PathLike, option: str = "--out") -> Path:
    """``path`` as an output folder that can be created and written, else a clear error (before any work;
    nothing is created)."""
    from pgc.io.atomic import check_folder

    out = Path(path)
    try:
        existing = check_folder(out)
    except PGCDataError as exc:
        raise PGCDataError(f"{option} {exc}") from None
    if not os.access(existing, os.W_OK | os.X_OK):
        raise PGCDataError(f"{option} {out}: {existing} is not writable; check its permissions or give another path")
    return out


def check_out_file(path: str | os.PathLike, option: str = "--out", example: str = "metrics.json") -> Path:
    """``path`` as an output file that can be written (its folder is created if missing), else a clear error
    before any work: a folder (``example``: a file name the message suggests inside it), a named pipe, a
    socket, a dangling link (:func:`pgc.io.atomic.write_target`), or a folder that cannot be made."""
    from pgc.io.atomic import write_target

    out = Path(path)
    if out.is_dir():
        raise PGCDataError(f"{option} {out}: is a folder; give a file path (e.g. {out / example})")
    try:
        write_target(out)
    except PGCDataError as exc:
        raise PGCDataError(f"{option} {exc}") from None
    check_out_folder(out.parent if str(out.parent) else Path("."), option=f"{option} {out}: folder")
    return out


def check_not_inside(out: str | os.PathLike, source: str | os.PathLike, what: str) -> None:
    """Refuse an output folder inside (or equal to) an input folder: the outputs would change the input."""
    out_r, src_r = Path(out).resolve(), Path(source).resolve()
    if out_r == src_r or src_r in out_r.parents:
        raise PGCDataError(f"--out {out}: lies inside the {what} {source}; writing there changes the input (and "
                           "its hash, so every rerun recomputes everything). Give a folder outside it")


@contextlib.contextmanager
def writing(folder: str | os.PathLike, command: str) -> Iterator[None]:
    """The exclusive lock of an output folder for the duration of a command (see :mod:`pgc.io.lock`); OS errors
    meanwhile name the folder when they name no file (:func:`pgc.checks.naming_output`)."""
    from pgc.io.lock import FolderLock

    with FolderLock(folder, command), naming_output(folder):
        yield




def read_json_object(path: Path, fix: str) -> dict[str, Any]:
    """A JSON object from ``path``, or a clear error naming the file (missing, malformed, not an object)."""
    from pgc.io.limits import read_json

    data = read_json(path, path.name, fix=fix)
    if not isinstance(data, dict):
        raise PGCDataError(f"{path}: must be a JSON object, got {type(data).__name__}; {fix}")
    return data


def check_run(run: str | os.PathLike) -> dict[str, Any]:
    """The ``run.json`` of a run folder after checking its fields and files, before any work."""
    run = Path(run)
    if not run.is_dir():
        raise PGCDataError(f"{run}: not a folder; give a run folder made by 'pgc animate'")
    fix = f"re-create the run with 'pgc animate ASSET --motion M --out {run}'"
    meta = read_json_object(run / "run.json", fix)
    for key, kind in (("asset", str), ("frames", int), ("fps", (int, float)), ("motion", str)):
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise PGCDataError(f"{run / 'run.json'}: field '{key}' is missing or not a {getattr(kind, '__name__', 'number')}"
                               f" (got {meta.get(key)!r}); {fix}")
    if meta["frames"] < 1:
        raise PGCDataError(f"{run / 'run.json'}: field 'frames' must be at least 1, got {meta['frames']}; {fix}")
    if meta.get("capture") is not None and not isinstance(meta["capture"], str):
        raise PGCDataError(f"{run / 'run.json'}: field 'capture' must be a folder path or null; {fix}")
    for name in ("garment.npz", "body.npz"):
        check_frames_file(run / name, meta["frames"], fix)
    from pgc.io.asset import read_manifest

    read_manifest(meta["asset"])
    return meta


def check_frames_file(path: Path, frames: int, fix: str) -> None:
    """A run's ``garment.npz``/``body.npz``: a readable archive (no pickles) with finite ``vertices``
    (frames, V, 3) and integer ``faces`` (F, 3) indexing them, else a clear error naming the file."""
    import zipfile

    import numpy as np

    if not path.is_file():
        raise PGCDataError(f"{path}: not found; the run folder is incomplete: {fix}")
    try:
        with np.load(path, allow_pickle=False) as z:
            vertices, faces = z["vertices"], z["faces"]
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise PGCDataError(f"{path}: not a readable run file ({type(exc).__name__}: {exc}); {fix}") from None
    if not np.issubdtype(vertices.dtype, np.number) or vertices.shape[:1] != (frames,) or vertices.ndim != 3 \
            or vertices.shape[2] != 3:
        raise PGCDataError(f"{path}: 'vertices' must be ({frames}, V, 3) numbers (run.json says {frames} frames), "
                           f"got {vertices.dtype} {vertices.shape}; {fix}")
    if not np.all(np.isfinite(vertices)):
        raise PGCDataError(f"{path}: 'vertices' holds non-finite positions; {fix}")
    if not np.issubdtype(faces.dtype, np.integer) or faces.ndim != 2 or faces.shape[1:] != (3,) or not faces.size \
            or faces.min() < 0 or faces.max() >= vertices.shape[1]:
        raise PGCDataError(f"{path}: 'faces' must be (F, 3) integer indices of its {vertices.shape[1]} vertices; "
                           f"{fix}")
