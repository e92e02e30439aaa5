"""2D keypoints of a capture's views, optional: ``CAPTURE/keypoints/<view>.json`` per view (``<view>`` the frame's
``pgc_name``, the camera name), each ``{"joints": {"<joint>": [x, y, confidence], ...}}`` with the body model's
joint names (Anny: the CMU rig's ``Head``, ``LeftArm``, ...), x and y in pixels (pixel centres at integer + 0.5)
and confidence in [0, 1]. The body fit uses them where present."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Mapping

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.atomic import write_json
from pgc.io.limits import read_json

KEYPOINTS_DIR = "keypoints"
FIX = 'each file is {"joints": {"<joint name>": [x_px, y_px, confidence 0..1], ...}}'


def keypoints_path(capture_root: str | os.PathLike, view: str) -> Path:
    return Path(capture_root) / KEYPOINTS_DIR / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', view)}.json"


def write_keypoints(capture_root: str | os.PathLike, view: str, joints: Mapping[str, tuple[float, float, float]]
                    ) -> Path:
    """Write one view's keypoints (name -> (x, y, confidence)); returns the file."""
    path = keypoints_path(capture_root, view)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, {"joints": {k: [float(x) for x in v] for k, v in joints.items()}})
    return path


def read_keypoints(capture_root: str | os.PathLike, views: list[str]):
    """view name -> :class:`pgc.body.fit.Keypoints` for the views that have a file; None when the capture has no
    ``keypoints/`` folder."""
    from pgc.body.fit import Keypoints

    if not (Path(capture_root) / KEYPOINTS_DIR).is_dir():
        return None
    out = {}
    for view in views:
        path = keypoints_path(capture_root, view)
        if not path.is_file():
            continue
        doc = read_json(path, "keypoints file", fix=FIX)
        joints = doc.get("joints") if isinstance(doc, dict) else None
        if not isinstance(joints, dict):
            raise PGCDataError(f"{path}: no 'joints' object; {FIX}")
        names, rows = [], []
        for name, value in joints.items():
            row = np.asarray(value, dtype=np.float64) if isinstance(value, list) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in value) else np.zeros(0)
            if row.shape != (3,) or not np.all(np.isfinite(row)) or not 0.0 <= row[2] <= 1.0:
                raise PGCDataError(f"{path}: joint '{name}' must be [x, y, confidence] (finite; confidence in "
                                   f"[0, 1]), got {value!r:.60}; {FIX}")
            names.append(name)
            rows.append(row)
        if rows:
            rows = np.array(rows)
            out[view] = Keypoints(tuple(names), rows[:, :2], rows[:, 2])
    return out
