"""pbr_renderer: a folded cloth sheet (self-shadowing, inter-reflection) with a checker base colour and the
paper's BRDF, under a constant light (and an environment map), in screen and/or texture space.

Reference (speed base and truth): the ``mitsuba`` path tracer at ``reference_spp`` samples per pixel.
Errors on pixels/texels covered in both: ``rel_mae`` (mean absolute error over the mean reference radiance,
plotted) and ``psnr_db`` (linear radiance, peak 1; higher is better).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "rel_mae"
MATERIAL = {"roughness": 0.8, "sheen_color": [0.6, 0.55, 0.35], "sheen_roughness": 0.35}


def scene(size: int) -> tuple[Any, Any, Any, dict[str, Any]]:
    """(mesh, material, camera, lights by name) of the folded-sheet scene seen at ``size`` px."""
    from pgc.testing.pbr_scenes import checker_texture, folded_sheet, ring_cameras
    from pgc.types import Light, Material

    env = np.tile(np.array([0.15, 0.2, 0.35], np.float32), (16, 32, 1))
    env[:8, 8:16] = [3.0, 2.6, 1.8]  # a bright window above
    lights = {"constant": Light(np.array([1.5, 1.4, 1.2])), "envmap": Light(np.ones(3), envmap=env, rotation_deg=30.0)}
    camera = ring_cameras(3, size=size, radius=1.8, arc_deg=100, elevation_deg=20)[1]
    return folded_sheet(n=24), Material("pgc-sheen", MATERIAL, checker_texture(64)), camera, lights


def renderer_call(renderer: Any, space: str, mesh: Any, material: Any, light: Any, camera: Any,
                  size: int) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
    """A function returning (radiance (H, W, 3), covered (H, W) bool) in ``space``."""
    if space == "screen":
        def screen() -> tuple[np.ndarray, np.ndarray]:
            out = renderer.render(mesh, material, light, camera)
            return out.color, out.alpha > 0.999
        return screen

    def texture() -> tuple[np.ndarray, np.ndarray]:
        radiance, coverage = renderer.render_texture(mesh, material, light, camera, (size, size))
        return radiance, coverage > 0.99
    return texture


def errors(img: np.ndarray, mask: np.ndarray, ref: np.ndarray, ref_mask: np.ndarray) -> dict[str, float]:
    from pgc.brdfs.fitdata import psnr_from_mse

    m = mask & ref_mask
    if not m.any():
        raise ValueError("pbr bench: the render covers none of the reference's pixels")
    d = np.asarray(img, np.float64)[m] - ref[m]
    return {"rel_mae": float(np.abs(d).mean() / max(float(np.abs(ref[m]).mean()), 1e-12)),
            "psnr_db": psnr_from_mse(float(np.mean(d ** 2)))}


def bench(ctx: Context) -> list[dict[str, Any]]:
    size, repeats = int(ctx.param("size", 32)), int(ctx.param("repeats", 1))
    ref_spp = int(ctx.param("reference_spp", 256))
    mesh, material, camera, lights = scene(size)
    reference = ctx.registry.get("pbr_renderer", "mitsuba").create({"spp": ref_spp})
    renderers = [ctx.build(run) for run in ctx.runs]
    records = []
    for light_name in ctx.param("lights", ["constant"]):
        for space in ctx.param("spaces", ["screen"]):
            case = f"{light_name} {space} {size}px"
            base = {"size": size, "light": light_name, "space": space}
            t = timed(renderer_call(reference, space, mesh, material, lights[light_name], camera, size), 1)
            ref, ref_mask = np.asarray(t.value[0], np.float64), t.value[1]
            records.append(ctx.record("mitsuba", case, base | {"options": {"spp": ref_spp}}, t.seconds, t.peak_mb,
                                      {"rel_mae": 0.0}, ERROR_KEY, reference=True))
            for i, run in enumerate(ctx.runs):
                settings = base | {"options": run.options}
                try:
                    if isinstance(renderers[i], Exception):
                        raise renderers[i]
                    t = timed(renderer_call(renderers[i], space, mesh, material, lights[light_name], camera, size),
                              repeats)
                    errs = errors(t.value[0], t.value[1], ref, ref_mask)
                except Exception as exc:  # a failing renderer is reported, the others still run
                    records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
                    continue
                records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb, errs, ERROR_KEY))
    return records
