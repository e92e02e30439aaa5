"""The light a run's frames were rendered under, as a JSON record: ``pgc render`` writes it into
``render.json`` (field ``light``), ``pgc eval`` checks it, renders the ground truth under it and copies it into
``metrics.json``, and a folder of pre-rendered ground-truth images states its own in ``light.json``.

Record::

    {"kind": "capture"}                                   the capture's light (constant radiance)
    {"kind": "envmap", "file": "sky.exr", "path": "/abs/sky.exr", "sha256": "<64 hex>",
     "rotation_deg": 30.0}                                an environment map turned 30 degrees about +Y
    {"kind": "envmap", ..., "frames": [0, 5, 10], "rotation_deg": [0.0, 120.0, 240.0]}   one angle per frame

Only the standard library is imported here (``pgc info`` reads records).
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

from pgc.errors import PGCDataError

LIGHT_KINDS = ("capture", "envmap")
"""The light kinds ``pgc eval`` can render ground truth under."""
SCENE_LIGHT = {"capture": "constant", "envmap": "envmap"}
"""Record kind -> the :class:`pgc.types.Light` kind a scene renderer must support (``light_kinds``)."""
GT_LIGHT_FILE = "light.json"
"""The light record of a folder of ground-truth images (``frame_XXXX_CAMERA.png``)."""
ROTATION_DIGITS = 6
"""Rotations (degrees) are compared and keyed rounded to this many decimals."""


def sha256_file(path: str | Path) -> str:
    """The full sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def capture_record() -> dict[str, Any]:
    """The record of the capture's own light."""
    return {"kind": "capture"}


def envmap_record(path: str | Path, frames: list[int], rotation_deg: list[float] | float) -> dict[str, Any]:
    """The record of the environment map at ``path`` (name, absolute path, sha256) turned ``rotation_deg``
    degrees about +Y: one number for every frame, or one per frame of ``frames``."""
    p = Path(path).resolve()
    record: dict[str, Any] = {"kind": "envmap", "file": p.name, "path": str(p), "sha256": sha256_file(p)}
    if isinstance(rotation_deg, (int, float)):
        record["rotation_deg"] = float(rotation_deg)
    else:
        if len(rotation_deg) != len(frames):
            raise ValueError(f"{len(rotation_deg)} rotations for {len(frames)} frames")
        record["frames"] = [int(t) for t in frames]
        record["rotation_deg"] = [float(r) for r in rotation_deg]
    return record


def rotation_at(record: dict[str, Any], frame: int) -> float:
    """The environment's rotation about +Y (degrees) at ``frame`` (KeyError if the record has no angle for it)."""
    rot = record.get("rotation_deg", 0.0)
    if not isinstance(rot, list):
        return float(rot)
    frames = record.get("frames") or []
    if frame not in frames:
        raise KeyError(frame)
    return float(rot[frames.index(frame)])


def check_record(record: Any, where: str, fix: str) -> dict[str, Any]:
    """``record`` once it is a well-formed light record (kind, file fields, rotations), else an error naming
    ``where`` (the file and field) and ``fix``."""
    if not isinstance(record, dict) or not isinstance(record.get("kind"), str):
        raise PGCDataError(f"{where}: a light record must be an object with a 'kind' ({' or '.join(LIGHT_KINDS)}); "
                           f"{fix}")
    if record["kind"] != "envmap":
        return record
    for name in ("file", "sha256"):
        if not isinstance(record.get(name), str) or not record[name]:
            raise PGCDataError(f"{where}: the environment map's '{name}' is not recorded; {fix}")
    rot = record.get("rotation_deg", 0.0)
    if isinstance(rot, list):
        frames = record.get("frames")
        if (not isinstance(frames, list) or len(frames) != len(rot)
                or not all(isinstance(t, int) and not isinstance(t, bool) for t in frames)):
            raise PGCDataError(f"{where}: 'rotation_deg' is a list, so 'frames' must list one frame number per "
                               f"angle; {fix}")
        values = rot
    else:
        values = [rot]
    if not all(isinstance(r, (int, float)) and not isinstance(r, bool) and math.isfinite(r) for r in values):
        raise PGCDataError(f"{where}: 'rotation_deg' must be finite degrees (a number or one per frame); {fix}")
    return record


def render_light(render_meta: dict[str, Any], meta_path: Path, frames: list[int], fix: str) -> dict[str, Any]:
    """The light record of a run's renders (``render.json`` field ``light``), checked: renders of the capture
    light (also those written before the record existed) give :func:`capture_record`; an environment map must
    name its file, which must still exist with the recorded sha256, and give an angle for every rendered frame.
    Anything else is a :class:`PGCDataError` naming the field and ``fix``."""
    light = render_meta.get("light")
    if light is None:
        return capture_record()
    where = f"{meta_path}: field 'light'"
    if not isinstance(light, dict):
        raise PGCDataError(f"{where} must be an object; {fix}")
    if "kind" not in light:  # written before the record: only the capture light can be reproduced
        if light.get("envmap"):
            raise PGCDataError(f"{where} says an environment map lit the frames but not which file (rendered before "
                               f"the light was recorded); {fix}")
        return capture_record()
    record = check_record(light, where, fix)
    if record["kind"] == "capture":
        return capture_record()
    if record["kind"] not in LIGHT_KINDS:
        raise PGCDataError(f"{where}: the frames were rendered under a '{record['kind']}' light, which ground truth "
                           f"cannot be rendered under (only {' or '.join(LIGHT_KINDS)}: the capture light or an "
                           f"environment map file); {fix}")
    path = Path(record.get("path") or record["file"])
    if not path.is_file():
        raise PGCDataError(f"{where}: the environment map {path} the frames were lit by no longer exists; put it "
                           f"back, or {fix}")
    if sha256_file(path) != record["sha256"]:
        raise PGCDataError(f"{where}: the environment map {path} changed since the frames were rendered (sha256 "
                           f"{record['sha256'][:12]}... recorded); restore it, or {fix}")
    try:
        for t in frames:
            rotation_at(record, t)
    except KeyError as exc:
        raise PGCDataError(f"{where}: no light rotation recorded for rendered frame {exc.args[0]}; {fix}") from None
    return record


def identity(record: dict[str, Any], frames: list[int]) -> dict[str, Any]:
    """What decides the light of ``frames``: the kind, and for an environment map its sha256 and the rotation
    of each frame (rounded to :data:`ROTATION_DIGITS`). Part of the ground-truth cache key; equal identities
    mean the same light."""
    if record.get("kind") != "envmap":
        return {"kind": record.get("kind")}
    return {"kind": "envmap", "sha256": record.get("sha256"),
            "rotation_deg": [[int(t), round(rotation_at(record, t), ROTATION_DIGITS)] for t in frames]}


def public(record: dict[str, Any], frames: list[int]) -> dict[str, Any]:
    """The record as ``metrics.json`` holds it: kind; for an environment map its file name, sha256 and rotation
    in degrees (one per evaluated frame when it turns)."""
    if record.get("kind") != "envmap":
        return {"kind": record.get("kind")}
    out = {"kind": "envmap", "file": record.get("file"), "sha256": record.get("sha256")}
    if isinstance(record.get("rotation_deg"), list):
        return {**out, "frames": list(frames), "rotation_deg": [rotation_at(record, t) for t in frames]}
    return {**out, "rotation_deg": float(record.get("rotation_deg", 0.0))}


def same_light(a: dict[str, Any], b: dict[str, Any], frames: list[int]) -> bool:
    """Whether two records give the same light on every one of ``frames`` (a missing angle is a difference)."""
    try:
        return identity(a, frames) == identity(b, frames)
    except (KeyError, ValueError):
        return False


def describe(record: Any) -> str:
    """One short line about a light record (for ``pgc info`` and the report)."""
    if not isinstance(record, dict):
        return "a light that was not recorded"
    if record.get("kind") == "capture":
        return "the capture light"
    if record.get("kind") != "envmap":
        return f"a '{record.get('kind')}' light"
    rot = record.get("rotation_deg", 0.0)
    if isinstance(rot, list) and rot:
        turn = f"rotating {min(rot):.0f}-{max(rot):.0f} deg over {len(rot)} frames"
    else:
        turn = f"rotation {rot:.4g} deg" if isinstance(rot, (int, float)) else "rotation not recorded"
    return f"environment map {record.get('file')} (sha256 {str(record.get('sha256'))[:12]}), {turn}"
