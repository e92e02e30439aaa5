"""simulator: the synthetic t-shirt on the synthetic body (the default Anny body), settled, blended into a motion and simulated.

Reference (speed base and truth): the ``reference`` implementation (default ``xpbd-jax``) with
``reference_options`` (default 4x the iterations: the converged answer of the same model). Errors:
``shape_diff_mean`` (metres, mean over motion frames of the mean vertex distance to the reference, plotted),
``shape_diff_max``, ``residual_rms`` (mean over frames of the constraint residual), ``max_stretch_strain`` and
``max_penetration_fraction``; per-frame values in the detail file. ``seconds`` is the whole ``simulate`` call
(settle + blend + motion frames), after one warm-up call (JIT compilation) for the implementations listed in
``warmup`` (default: all; eager ones gain nothing from it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "shape_diff_mean"


def scene(body_model: Any, resolution: float, motion: str, seconds: float) -> tuple[Any, Any]:
    """(t-shirt mesh with ``resolution`` m edges, motion ``motion`` of ``seconds`` at 30 fps) on the default body
    of ``body_model``."""
    from pgc.synth.body import make_body
    from pgc.synth.garments import make_garment
    from pgc.synth.motions import make_motion

    body = make_body(body_model)
    return make_garment(body, "tshirt", resolution=resolution), make_motion(body, motion, seconds=seconds)


def errors(sim: Any, ref: np.ndarray) -> tuple[dict[str, float], dict[str, Any]]:
    d = np.linalg.norm(sim.vertices.astype(np.float64) - ref, axis=-1)  # (frames, vertices)
    f = sim.figures
    errs = {"shape_diff_mean": float(d.mean()), "shape_diff_max": float(d.max()),
            "residual_rms": float(np.mean(f["residual_rms"])), "max_stretch_strain": float(np.max(f["max_stretch_strain"])),
            "max_penetration_fraction": float(f["max_penetration_fraction"])}
    detail = {"shape_diff_mean_per_frame": d.mean(1).tolist(), "residual_rms": f["residual_rms"],
              "max_stretch_strain": f["max_stretch_strain"], "penetration_fraction": f["penetration_fraction"]}
    return errs, detail


def bench(ctx: Context) -> list[dict[str, Any]]:
    resolution, motion_name = float(ctx.param("resolution", 0.04)), ctx.param("motion", "goalpost")
    body_model = ctx.registry.create("body_model", ctx.param("body_model", "anny"))
    garment, motion = scene(body_model, resolution, motion_name, float(ctx.param("seconds", 0.1)))
    common = {"settle_frames": int(ctx.param("settle_frames", 2)), "blend_frames": int(ctx.param("blend_frames", 2))}
    ref_name = ctx.param("reference", "xpbd-jax")
    ref_options = common | ctx.param("reference_options", {"iterations": 80})
    case = f"tshirt {len(garment.vertices)} vertices, {motion_name} {motion.num_frames} frames"
    base = {"vertices": len(garment.vertices), "frames": motion.num_frames, "motion": motion_name}
    reference = ctx.registry.get("simulator", ref_name).create(ref_options)
    t = timed(lambda: reference.simulate(garment, motion), 1)
    ref = t.value.vertices.astype(np.float64)
    errs, detail = errors(t.value, ref)
    records = [ctx.record(ref_name, case, base | {"options": ref_options}, t.seconds, t.peak_mb, errs, ERROR_KEY,
                          reference=True, detail=detail)]
    warmup = ctx.param("warmup", None)
    for run in ctx.runs:
        settings = base | {"options": run.options, "warmup": warmup is None or run.implementation in warmup}
        try:
            sim = ctx.create(run, **{k: v for k, v in common.items() if k not in run.all_options})
            t = timed(lambda: sim.simulate(garment, motion), int(ctx.param("repeats", 1)), settings["warmup"])
        except Exception as exc:  # a diverging or failing simulator is reported, the others still run
            records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
            continue
        errs, detail = errors(t.value, ref)
        records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb, errs, ERROR_KEY,
                                  detail=detail))
    return records
