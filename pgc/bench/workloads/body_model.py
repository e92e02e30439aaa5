"""body_model: skin a clip of random joint rotations (the body's default shape).

Reference (speed base and truth): linear blend skinning written out in numpy on the same body's rest mesh,
weights and per-frame joint transforms (from ``forward``). Error ``max_vertex_diff_m`` (plotted): the largest
distance, metres, between the implementation's ``skin`` and that reference over all frames; SMPL-family models
add pose-corrective blend shapes that plain skinning lacks, so their difference is those correctives (mm).
A ``model_path`` of ``"{tiny_smpl}"`` (the default matrix's, for ``smplx``) is the in-process SMPL-format test
file (:mod:`pgc.testing.body_scenes`): the licensed model files cannot ship.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "max_vertex_diff_m"
TINY_SMPL = "{tiny_smpl}"
"""A ``model_path`` naming the tiny SMPL-format test file, written for the run."""


def random_clip(joints: int, frames: int, seed: int = 0) -> np.ndarray:
    """(frames, joints, 3, 3) rotations about random axes, angles ~ N(0, 0.3) radians per component."""
    from pgc.motion.rotations import axis_angle_to_matrix

    return axis_angle_to_matrix(np.random.default_rng(seed).normal(0.0, 0.3, (frames, joints, 3)))


def numpy_skinning(rest: np.ndarray, weights: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """(T, V, 3) float32: rest vertices (V, 3) moved by the weight blend (V, J) of joint transforms (T, J, 4, 4)."""
    blended = np.einsum("vj,tjab->tvab", weights, transforms)
    return (np.einsum("tvab,vb->tva", blended[..., :3, :3], rest) + blended[..., :3, 3]).astype(np.float32)


def bench(ctx: Context) -> list[dict[str, Any]]:
    frames, repeats = int(ctx.param("frames", 30)), int(ctx.param("repeats", 3))
    records: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as scratch:
        for run in ctx.runs:
            settings: dict[str, Any] = {"frames": frames, "options": run.options}
            case = f"{run.implementation}-{frames}f"
            try:
                overrides: dict[str, Any] = {}
                if run.all_options.get("model_path") == TINY_SMPL:
                    from pgc.testing.body_scenes import write_tiny_smpl

                    overrides["model_path"] = str(write_tiny_smpl(Path(scratch) / "SMPL_TINY.pkl"))
                    settings["model"] = "tiny SMPL-format test file (pgc.testing.body_scenes)"
                body = ctx.create(run, **overrides)
                clip = random_clip(len(body.joint_names), frames)
                rest = body.forward().vertices
                transforms = np.stack([body.forward(None, r).transforms for r in clip])
                reference = timed(lambda: numpy_skinning(rest, body.weights, transforms), repeats)
                skinned = timed(lambda: body.skin(None, clip), repeats)
            except Exception as exc:  # a failing body model is reported, the others still run
                records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
                continue
            settings |= {"vertices": int(len(rest)), "joints": len(body.joint_names)}
            records.append(ctx.record("numpy-lbs", case, settings, reference.seconds, reference.peak_mb,
                                      {ERROR_KEY: 0.0}, ERROR_KEY, reference=True))
            diff = float(np.linalg.norm(skinned.value.astype(np.float64) - reference.value, axis=-1).max())
            records.append(ctx.record(run.implementation, case, settings, skinned.seconds, skinned.peak_mb,
                                      {ERROR_KEY: diff}, ERROR_KEY))
    return records
