"""brdf: ``eval_cos`` on N random direction pairs (some at grazing angles, some below the surface) per
array backend.

Reference (speed base and truth): the same BRDF evaluated by the numpy backend in float64. Other backends
run in float32 (JAX jitted, torch eager). Errors: ``max_abs`` (plotted) and ``max_rel`` (over the largest
reference value) against the numpy values, and ``nonfinite`` (count of NaN/Inf outputs, must be 0).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "max_abs"


def directions(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(wi, wo, base_color), float64: unit vectors (5% grazing within 1e-6 of the surface, 5% below it)."""
    rng = np.random.default_rng(seed)

    def unit(z_low: float) -> np.ndarray:
        v = rng.standard_normal((n, 3))
        v[:, 2] = np.abs(v[:, 2]) + z_low
        k = n // 20
        v[:k, 2] = rng.uniform(0, 1e-6, k) * np.linalg.norm(v[:k, :2], axis=1)  # grazing
        v[k:2 * k, 2] *= -1.0  # below the surface
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    return unit(0.0), unit(0.0)[rng.permutation(n)], rng.uniform(0.05, 0.95, (n, 3))


def evaluator(brdf: Any, backend: str, wi: np.ndarray, wo: np.ndarray, bc: np.ndarray,
              params: dict[str, Any]) -> Callable[[], np.ndarray]:
    """A function evaluating ``brdf`` on ``backend`` (inputs converted once, outside the timing)."""
    if backend == "numpy":
        return lambda: brdf.eval_cos(wi, wo, bc, params, "numpy")
    if backend == "torch":
        import torch

        a, b, c = (torch.from_numpy(x.astype(np.float32)) for x in (wi, wo, bc))

        def run_torch() -> np.ndarray:
            with torch.no_grad():
                return brdf.eval_cos(a, b, c, params, "torch").numpy()
        return run_torch
    if backend == "jax":
        import jax
        import jax.numpy as jnp

        a, b, c = (jnp.asarray(x, jnp.float32) for x in (wi, wo, bc))
        fn = jax.jit(lambda x, y, z: brdf.eval_cos(x, y, z, params, "jax"))
        return lambda: np.asarray(jax.block_until_ready(fn(a, b, c)))
    raise ValueError(f"brdf bench: backend '{backend}' is not measured here; use numpy, torch or jax")


def by_group(out: np.ndarray, ref: np.ndarray, n: int) -> dict[str, float]:
    """Largest absolute difference on the pairs whose ``wi`` is grazing, below the surface, or neither."""
    d = np.abs(np.asarray(out, np.float64) - ref).max(axis=-1)
    k = n // 20
    return {"max_abs_grazing": float(d[:k].max(initial=0.0)), "max_abs_below": float(d[k:2 * k].max(initial=0.0)),
            "max_abs_other": float(d[2 * k:].max(initial=0.0))}


def errors(out: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    out = np.asarray(out, np.float64)
    d = np.abs(np.where(np.isfinite(out), out, np.inf) - ref)
    return {"max_abs": float(d.max()), "max_rel": float(d.max() / max(float(np.abs(ref).max()), 1e-30)),
            "nonfinite": float(np.count_nonzero(~np.isfinite(out)))}


def bench(ctx: Context) -> list[dict[str, Any]]:
    n, repeats = int(ctx.param("directions", 20_000)), int(ctx.param("repeats", 3))
    backends = [b for b in ctx.param("backends", ["numpy", "torch", "jax"]) if b != "numpy"]
    wi, wo, bc = directions(n)
    records = []
    for run in ctx.runs:
        case = f"{run.implementation} n={n}"
        base = {"directions": n, "options": run.options}
        try:
            brdf = ctx.create(run)
            params = brdf.initial_params()
            t = timed(evaluator(brdf, "numpy", wi, wo, bc, params), repeats)
        except Exception as exc:  # a broken BRDF is reported, the others still run
            records.append(ctx.failed(run.implementation, case, base | {"backend": "numpy"}, exc, ERROR_KEY))
            continue
        ref = np.asarray(t.value, np.float64)
        records.append(ctx.record(run.implementation, case, base | {"backend": "numpy", "dtype": "float64"},
                                  t.seconds, t.peak_mb, errors(ref, ref), ERROR_KEY, reference=True,
                                  label=f"{run.implementation}/numpy"))
        for backend in backends:
            settings = base | {"backend": backend, "dtype": "float32"}
            try:
                t = timed(evaluator(brdf, backend, wi, wo, bc, params), repeats)
            except Exception as exc:  # e.g. a backend library that is not installed
                records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
                continue
            records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb,
                                      errors(t.value, ref), ERROR_KEY, label=f"{run.implementation}/{backend}",
                                      detail=by_group(t.value, ref, n)))
    return records
