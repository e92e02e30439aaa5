"""The slow, obviously-correct per-pixel float64 rasteriser: the test oracle of every splat backend.

Per pixel centre c = (x + 0.5, y + 0.5): take the projected Gaussians whose footprint box contains c
(:mod:`pgc.splats.projection`), in increasing camera depth (ties by index), and composite front to back:
``alpha = min(0.99, o exp(-0.5 d^T conic d))`` with d = c - mean2d; alpha < 1/255 is skipped; a Gaussian
whose inclusion would bring the transmittance below 1e-4 is not included and compositing stops (the 3DGS
rule). colour = sum T_i alpha_i c_i + T_final background, alpha = 1 - T_final,
depth = sum T_i alpha_i z_i / alpha (0 where alpha is 0).
"""

from __future__ import annotations

import numpy as np

from pgc.checks import require_finite
from pgc.roles.splat_renderer import RenderOutput, check_render_inputs
from pgc.splats.projection import ALPHA_MAX, ALPHA_MIN, T_MIN, project
from pgc.types import Camera, WorldGaussians


def background_image(background: np.ndarray | None, height: int, width: int) -> np.ndarray:
    """(H, W, 3) float64 background from None (black), an (3,) colour or an (H, W, 3) image."""
    if background is None:
        return np.zeros((height, width, 3))
    bg = np.asarray(background, np.float64)
    require_finite("splat renderer", "background", bg)
    if bg.shape == (3,):
        return np.broadcast_to(bg, (height, width, 3)).copy()
    if bg.shape != (height, width, 3):
        raise ValueError(f"background must be (3,) or (H, W, 3) = {(height, width, 3)}, got {bg.shape}")
    return bg


def render_reference(world: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
                     sh_degree: int | None = None, near: float = 0.01) -> RenderOutput:
    """Render by looping over pixels and, inside each pixel, over its depth-sorted Gaussians (float64)."""
    check_render_inputs(world, background, "render_reference")
    h, w = camera.height, camera.width
    bg = background_image(background, h, w)
    p = project(world, camera, sh_degree, near)
    order = [i for i in np.argsort(p.depths, kind="stable") if p.valid[i]]
    color, alpha, depth = np.zeros((h, w, 3)), np.zeros((h, w)), np.zeros((h, w))
    for py in range(h):
        for px in range(w):
            cx, cy = px + 0.5, py + 0.5
            T, acc_c, acc_z = 1.0, np.zeros(3), 0.0
            for i in order:
                dx, dy = cx - p.means2d[i, 0], cy - p.means2d[i, 1]
                if abs(dx) > p.radii[i] or abs(dy) > p.radii[i]:
                    continue
                a, b, c = p.conics[i]
                g = np.exp(-0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy)
                al = min(ALPHA_MAX, p.opacities[i] * g)
                if al < ALPHA_MIN:
                    continue
                if T * (1.0 - al) < T_MIN:
                    break
                acc_c += T * al * p.colors[i]
                acc_z += T * al * p.depths[i]
                T *= 1.0 - al
            color[py, px] = acc_c + T * bg[py, px]
            alpha[py, px] = 1.0 - T
            depth[py, px] = acc_z / (1.0 - T) if T < 1.0 else 0.0
    return RenderOutput(color=color, alpha=alpha, depth=depth)
