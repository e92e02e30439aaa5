"""Fitted-body files: ``body.json`` (the body model, its options, shape, pose and the fit's figures) and
``body.ply`` (the posed mesh, face label body), written by ``pgc body fit`` and the ``body_fit`` stage.

``body.json``::

    {"format": "pgc-body-fit", "version": 1, "model": "anny", "options": {"topology": ...},
     "shape": {"gender": 0.3, ...}, "joint_names": [...], "rotations": [[[...]]] (J, 3, 3),
     "translation": [x, y, z] (metres), "mesh": "body.ply", "figures": {...}}
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.atomic import ensure_folder, write_json
from pgc.io.limits import read_json
from pgc.io.mesh import read_mesh, write_mesh

BODY_FIT_DIR = "body_fit"
"""An asset's folder of the fitted body, for a capture without a ground-truth body (``pgc reconstruct``)."""
BODY_JSON = "body.json"
BODY_MESH = "body.ply"
FORMAT = "pgc-body-fit"
VERSION = 1
FIX = f"give the {BODY_JSON} (or its folder) that 'pgc body fit CAPTURE --out DIR' writes"


def write_body_fit(folder: str | os.PathLike, fit) -> Path:
    """Write ``fit`` (a :class:`pgc.body.fit.BodyFit`) into ``folder``; returns the path of its body.json."""
    folder = ensure_folder(folder)
    write_mesh(folder / BODY_MESH, fit.mesh)
    write_json(folder / BODY_JSON, {
        "format": FORMAT, "version": VERSION, "model": fit.model, "options": fit.options, "shape": fit.shape,
        "joint_names": list(fit.joint_names), "rotations": np.asarray(fit.rotations).tolist(),
        "translation": np.asarray(fit.translation).tolist(), "mesh": BODY_MESH, "figures": fit.figures})
    return folder / BODY_JSON


def read_body_fit(path: str | os.PathLike):
    """The :class:`pgc.body.fit.BodyFit` of a body.json (or its folder); one :class:`PGCDataError` naming the file,
    the field and the fix for anything else."""
    from pgc.body.fit import BodyFit

    path = Path(path)
    if path.is_dir():
        path = path / BODY_JSON
    if path.suffix.lower() != ".json":
        raise PGCDataError(f"{path}: not a fitted-body file ({path.suffix or 'no suffix'}); {FIX}")
    doc = read_json(path, "fitted body", fix=FIX)

    def fail(field: str, problem: str) -> PGCDataError:
        return PGCDataError(f"{path}: '{field}' {problem}; {FIX}")

    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise PGCDataError(f"{path}: not a fitted-body file (no \"format\": \"{FORMAT}\"); {FIX}")
    if doc.get("version") != VERSION:
        raise fail("version", f"is {doc.get('version')!r}; this PGC reads version {VERSION}")
    for field, kind in (("model", str), ("options", dict), ("shape", dict), ("joint_names", list),
                        ("mesh", str), ("figures", dict)):
        if not isinstance(doc.get(field), kind):
            raise fail(field, f"must be a {kind.__name__}")
    names = doc["joint_names"]
    if not names or not all(isinstance(n, str) for n in names):
        raise fail("joint_names", "must be a non-empty list of joint names")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
               for v in doc["shape"].values()):
        raise fail("shape", "must map each shape parameter to a finite number")
    try:
        rotations = np.asarray(doc.get("rotations"), dtype=np.float64)
        translation = np.asarray(doc.get("translation"), dtype=np.float64)
    except (TypeError, ValueError):
        raise fail("rotations", "and 'translation' must be arrays of numbers") from None
    if rotations.shape != (len(names), 3, 3) or not np.all(np.isfinite(rotations)):
        raise fail("rotations", f"must be {len(names)} finite 3x3 rotations (one per joint), got shape "
                                f"{rotations.shape}")
    if np.abs(np.einsum("jik,jil->jkl", rotations, rotations) - np.eye(3)).max() > 1e-4 \
            or np.linalg.det(rotations).min() < 0:
        raise fail("rotations", "must hold proper rotation matrices (orthonormal, det +1)")
    if translation.shape != (3,) or not np.all(np.isfinite(translation)):
        raise fail("translation", "must be 3 finite numbers (metres)")
    mesh_path = path.parent / doc["mesh"]
    if Path(doc["mesh"]).name != doc["mesh"] or not mesh_path.is_file():
        raise fail("mesh", f"names {doc['mesh']!r}, which is not a file beside it")
    return BodyFit(doc["model"], doc["options"], {k: float(v) for k, v in doc["shape"].items()}, tuple(names),
                   rotations, translation, read_mesh(mesh_path, name="body"), doc["figures"])
