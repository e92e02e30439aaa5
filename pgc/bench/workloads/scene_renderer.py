"""scene_renderer: path tracing one Lambertian triangle under a constant environment, speed against noise.

Every path of a fully covered pixel has the expected value ``albedo x L`` (nothing occludes the environment),
so the error is exact: the RMS relative deviation of those pixels from it (``rms_rel``, plotted) and of their
mean (``mean_rel``). Reference (speed base): the same implementation at 1 sample per pixel.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "rms_rel"
ALBEDO, RADIANCE, DEPTH = 0.5, (1.0, 0.8, 0.6), 2.0


def triangle_scene(size: int) -> tuple[Any, Any, np.ndarray]:
    """(camera, geometry, fully-covered pixel mask) of a triangle covering about a third of a square image."""
    from pgc.roles.scene_renderer import SceneGeometry
    from pgc.types import Camera, Material, Mesh

    camera = Camera(K=np.array([[1.6 * size, 0, size / 2], [0, 1.6 * size, size / 2], [0, 0, 1]]), R=np.eye(3),
                    t=np.zeros(3), width=size, height=size, name="front")
    corners = np.array([[0.15, 0.15], [0.85, 0.3], [0.35, 0.85]]) * size
    pix = np.c_[corners, np.ones(3)]
    triangle = Mesh(DEPTH * pix @ np.linalg.inv(camera.K).T, np.array([[0, 2, 1]]), name="garment")
    geometry = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), triangle,
                             Material("lambertian", {"base_color": [ALBEDO] * 3}))
    ys, xs = np.mgrid[0:size, 0:size]
    inside = np.ones((size, size), bool)
    for i in range(3):  # a pixel is fully covered when its four corners are inside every edge
        (x0, y0), (x1, y1) = corners[i], corners[(i + 1) % 3]
        for dx in (0, 1):
            for dy in (0, 1):
                inside &= (x1 - x0) * (ys + dy - y0) - (y1 - y0) * (xs + dx - x0) >= 0
    return camera, geometry, inside


def errors(color: np.ndarray, full: np.ndarray) -> dict[str, float]:
    expected = ALBEDO * np.asarray(RADIANCE)
    rel = np.asarray(color, np.float64)[full] / expected - 1.0
    return {"rms_rel": float(np.sqrt(np.mean(rel ** 2))), "mean_rel": float(np.abs(rel.mean(axis=0)).max())}


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.types import Light

    size, repeats = int(ctx.param("size", 32)), int(ctx.param("repeats", 2))
    camera, geometry, full = triangle_scene(size)
    records = []
    for run in ctx.runs:
        renderer = ctx.build(run)
        case = f"{size}px triangle"
        try:
            if isinstance(renderer, Exception):
                raise renderer
            scene, _ = renderer.build_scene(geometry, Light(np.asarray(RADIANCE)))
            base = timed(lambda: renderer.render_color(scene, camera, 1, 0)[0], repeats)
            records.append(ctx.record(run.implementation, case, {"spp": 1, "options": run.options}, base.seconds,
                                      base.peak_mb, errors(base.value, full), ERROR_KEY, reference=True,
                                      label=f"{run.implementation} 1 spp"))
            for spp in ctx.param("spp", [4, 16, 64]):
                t = timed(lambda: renderer.render_color(scene, camera, int(spp), 0)[0], repeats)
                records.append(ctx.record(run.implementation, case, {"spp": int(spp), "options": run.options},
                                          t.seconds, t.peak_mb, errors(t.value, full), ERROR_KEY,
                                          label=f"{run.implementation} {spp} spp"))
        except Exception as exc:  # a failing backend is reported, the others still run
            records.append(ctx.failed(run.implementation, case, {"options": run.options}, exc, ERROR_KEY))
    return records
