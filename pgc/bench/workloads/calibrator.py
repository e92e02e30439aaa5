"""calibrator: refining the poses of a textured cube's capture whose true poses are known.

The input poses are perturbed (seeded: ``perturb_deg`` about a random axis, ``perturb_m`` along a random
direction); errors are the refined poses' mean rotation error (``rotation_deg``, plotted) and camera-centre
error (``centre_m``) against the truth, and the share of views registered. Reference: the perturbed input
itself (zero seconds of work, its errors are what calibration must remove).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "rotation_deg"


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def pose_errors(cameras: list, truth: list) -> dict[str, float]:
    rot = [np.degrees(np.arccos(np.clip((np.trace(a.R.T @ b.R) - 1) / 2, -1.0, 1.0))) for a, b in zip(cameras, truth)]
    centre = [np.linalg.norm(a.center - b.center) for a, b in zip(cameras, truth)]
    return {"rotation_deg": float(np.mean(rot)), "centre_m": float(np.mean(centre))}


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.testing.capture_scenes import textured_box_capture

    views, size = int(ctx.param("views", 8)), int(ctx.param("size", 192))
    degrees, metres = float(ctx.param("perturb_deg", 1.0)), float(ctx.param("perturb_m", 0.01))
    truth = textured_box_capture(views, size)
    rng = np.random.default_rng(0)
    perturbed = []
    for v in truth.views:
        R = _rotation(rng.normal(size=3), np.radians(degrees)) @ v.camera.R
        centre = v.camera.center + metres * rng.normal(size=3) / np.sqrt(3)
        perturbed.append(replace(v, camera=replace(v.camera, R=R, t=-R @ centre)))
    given = replace(truth, views=perturbed)
    case = f"cube {views} views {size}px, {degrees} deg / {metres} m off"
    records = [ctx.record("input-poses", case, {"views": views}, 0.0, 0.0,
                          pose_errors([v.camera for v in given.views], truth.cameras), ERROR_KEY, reference=True)]
    for run in ctx.runs:
        calibrator = ctx.build(run)
        try:
            if isinstance(calibrator, Exception):
                raise calibrator
            t = timed(lambda: calibrator.calibrate(given), 1, warmup=False)
            out = t.value
            errs = pose_errors(out.capture.cameras, truth.cameras)
            errs["registered_fraction"] = float(out.figures.get("registered_views", views)) / views
            records.append(ctx.record(run.implementation, case, {"views": views, "options": run.options},
                                      t.seconds, t.peak_mb, errs, ERROR_KEY))
        except Exception as exc:  # a failing backend is reported, the others still run
            records.append(ctx.failed(run.implementation, case, {"options": run.options}, exc, ERROR_KEY))
    return records
