"""Hybrid rendering of one frame (docs/method.md, section 5): ``I_t = h(G_t) + l(S_t)``.

- ``G_t``: the optimised Gaussians rendered on the deformed garment (near field);
- ``S_t``: the same Gaussians with their colour replaced by the far-field texture ``T_t`` (the PBR
  renderer's outgoing radiance in texture space) as the DC SH term (higher SH set to zero), all other
  parameters unchanged. The paper looks ``T_t`` up through each Gaussian's parent triangle
  (:func:`gaussian_uvs`, lookup ``parent``); the default lookup ``visible`` takes the texel of the garment
  surface seen along the camera ray through the Gaussian's centre (:func:`visible_surface_uvs`), which is the
  same texel for a Gaussian on the visible surface, and the right one for a Gaussian bound to a triangle that
  faces away but shows through or beside the front (those would carry the black radiance of a back face);
- the body occludes both: splat pixels whose depth lies behind the body's z-buffer are removed
  (:func:`hide_behind`);
- ``l``: the alpha-aware low-pass of the filter role, ``h = 1 - l``; with ``detail = 'multiplicative'`` the
  hybrid is ``l(S) G / l(G)`` instead, with ``'ratio'`` ``l(S) + h(G) l(S) / l(S_c)`` (``S_c`` the far field
  under the capture light), with ``'residual'`` ``S + l(S) (h(G) / l(G) - h(S_c) / l(S_c))``
  (:mod:`pgc.filtering.detail`).
Compositing is done on un-premultiplied colours (render colour / alpha) so the alpha-aware blur sees the
garment's own colour; the result is re-composited over the background with the alpha of the layer that
gives the garment its shape (``silhouette``): ``'near'``, the Gaussians' alpha (the paper, where ``S_t`` is the
same Gaussians and both alphas agree), or ``'far'``, the far field's alpha, with the detail ``h(G)`` weighted
by the near field's alpha (``l(S) + alpha_G h(G)``, so it fades out where the Gaussians do not cover). With
the mesh as far field, ``'far'`` is the simulated mesh's own coverage (docs/pipeline.md measures both).
With ``'far'``, ``outline_fade`` blends the hybrid into the far field over a band of the kernel's width
inside that outline: there the near field's high band is made from Gaussians that stick out of or thin out
at the deformed garment's edge, and the band belongs to the far field.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.filtering.detail import CAPTURE_FAR_FIELD_MODES, hybrid_colour
from pgc.geometry.raster import Raster
from pgc.roles.filter import Filter
from pgc.roles.splat_renderer import RenderOutput
from pgc.splats.binding import triangle_frames
from pgc.splats.sh import rgb_to_sh_dc
from pgc.texture.sample import sample_uv
from pgc.types import Camera, GaussianSet, Mesh

ALPHA_EPS = 1e-4


def gaussian_uvs(gaussians: GaussianSet, mesh: Mesh) -> np.ndarray:
    """(N, 2) UV of each Gaussian's foot point on its parent triangle (rest shape).

    The local mean ``mu`` is mapped to the world, projected onto the parent triangle's plane and expressed
    in barycentric coordinates (clamped into the triangle); the UV interpolates the corners' UVs. The
    binding is a similarity per triangle, so these coordinates do not change when the garment deforms.
    """
    tau, R, k = triangle_frames(mesh.vertices, mesh.faces)
    p = gaussians.parent
    world = np.einsum("nij,nj->ni", R[p], gaussians.means.astype(np.float64)) * k[p, None] + tau[p]
    corners = mesh.vertices[mesh.faces[p]]
    bary = _barycentric_clamped(world, corners)
    return np.einsum("nk,nkc->nc", bary, mesh.uv[mesh.face_uv[p]].astype(np.float64))


def visible_surface_uvs(means: np.ndarray, raster: Raster, mesh: Mesh, camera: Camera,
                        fallback: np.ndarray, reach: float = 2.0) -> np.ndarray:
    """(N, 2) UV of the surface point of ``mesh`` that ``camera`` sees through each world point ``means``.

    ``raster``: ``mesh`` (deformed as ``means``) rasterised from ``camera``. A point projecting onto an empty
    pixel within ``reach`` pixels of the silhouette takes the nearest covered pixel's surface point; points
    farther out or outside the image keep their ``fallback`` UV (their parent-triangle UV).
    """
    from scipy.ndimage import distance_transform_edt

    xy, z = camera.project(np.asarray(means, np.float64))
    h, w = raster.face_id.shape
    ok = (z > 0) & np.all(np.isfinite(xy), axis=1)
    col = np.floor(np.where(ok, xy[:, 0], -1)).astype(np.int64)
    row = np.floor(np.where(ok, xy[:, 1], -1)).astype(np.int64)
    ok &= (col >= 0) & (col < w) & (row >= 0) & (row < h)
    row, col = row.clip(0, h - 1), col.clip(0, w - 1)
    empty = raster.face_id < 0
    if empty.any() and not empty.all():
        dist, (near_row, near_col) = distance_transform_edt(empty, return_indices=True)
        ok &= dist[row, col] <= reach
        row, col = near_row[row, col], near_col[row, col]
    face = np.where(ok, raster.face_id[row, col], -1)
    hit = face >= 0
    uvs = np.array(fallback, dtype=np.float64, copy=True)
    bary = raster.bary[row[hit], col[hit]]
    uvs[hit] = np.einsum("nk,nkc->nc", bary, mesh.uv[mesh.face_uv[face[hit]]].astype(np.float64))
    return uvs


def hide_behind(render: RenderOutput, occluder_depth: np.ndarray, depth: np.ndarray | None = None) -> RenderOutput:
    """``render`` with pixels removed where the occluder's z-buffer (camera depth, +inf where empty) lies in
    front of ``depth`` (default: the render's expected depth, which averages over every splat layer of the
    pixel, so a garment's first surface, when known, is the better test)."""
    d = render.depth if depth is None else depth
    if d is None:
        raise ValueError("hide_behind needs the splat depth: the splat renderer returned none")
    keep = ~((occluder_depth < d) & (render.alpha > 0))
    return RenderOutput(render.color * keep[..., None], render.alpha * keep, d * keep)


def _barycentric_clamped(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    ok = den > 1e-30
    safe = np.where(ok, den, 1.0)
    v = np.where(ok, (d11 * d20 - d01 * d21) / safe, 1 / 3)
    w = np.where(ok, (d00 * d21 - d01 * d20) / safe, 1 / 3)
    bary = np.clip(np.stack([1 - v - w, v, w], axis=1), 0.0, None)
    return bary / bary.sum(1, keepdims=True)


def far_field_gaussians(gaussians: GaussianSet, uvs: np.ndarray, texture: np.ndarray) -> GaussianSet:
    """The Gaussians with colour from ``texture`` at ``uvs`` as their only (DC) SH term."""
    colors = np.clip(sample_uv(np.asarray(texture, np.float64), uvs), 0.0, None)
    sh = np.zeros((len(gaussians), 1, 3), np.float32)
    sh[:, 0] = rgb_to_sh_dc(colors)
    return GaussianSet(gaussians.parent, gaussians.means, gaussians.quats, gaussians.log_scales,
                       gaussians.opacity_logits, sh)


def unpremultiply(render: RenderOutput) -> np.ndarray:
    """Colour of the splats themselves, (H, W, 3): render colour (over black) / alpha; 0 where alpha ~ 0."""
    a = render.alpha[..., None]
    return np.where(a > ALPHA_EPS, render.color / np.maximum(a, ALPHA_EPS), 0.0).astype(np.float32)


@dataclass
class HybridFrame:
    hybrid: np.ndarray
    """(H, W, 3) h(G) + l(S) composited over the background with G's alpha."""
    near: np.ndarray
    """(H, W, 3) G over the background (the 3DGS-only ablation)."""
    far: np.ndarray
    """(H, W, 3) S over the background (the PBR-only ablation through the Gaussians)."""
    low_far: np.ndarray
    """(H, W, 3) l(S), un-premultiplied."""
    high_near: np.ndarray
    """(H, W, 3) h(G), un-premultiplied (signed)."""
    alpha: np.ndarray
    """(H, W) alpha of G."""
    hybrid_alpha: np.ndarray
    """(H, W) alpha the hybrid is composited with (G's or S's, see ``silhouette``)."""


def outline_weight(alpha: np.ndarray, width: float) -> np.ndarray:
    """(H, W) weight rising linearly from 0 at the outline of ``alpha > 0.5`` to 1 at ``width`` px inside it
    (the distance of a covered pixel's centre to the nearest uncovered one, minus half a pixel); 0 outside;
    all ones for ``width <= 0`` or when nothing is uncovered. The image border is not an outline."""
    from scipy.ndimage import distance_transform_edt

    covered = alpha > 0.5
    if width <= 0 or covered.all():
        return np.ones(alpha.shape, np.float32)
    return np.clip((distance_transform_edt(covered) - 0.5) / width, 0.0, 1.0).astype(np.float32)


def compose(near: RenderOutput, far: RenderOutput, filt: Filter, kernel_size: int,
            background: np.ndarray | None = None, silhouette: str = "near", outline_fade: float = 0.0,
            detail: str = "additive", far_capture: RenderOutput | None = None) -> HybridFrame:
    """Combine the near-field and far-field renders of one view (both rendered over black); ``silhouette``
    ('near' or 'far'): whose alpha shapes the hybrid (module docstring). ``outline_fade`` (with silhouette
    'far'): within ``outline_fade * kernel_size`` px of the far field's outline the hybrid blends linearly
    into the far field itself (:func:`outline_weight`), so the outline band shows no near-field detail; 0
    turns it off. ``detail``: how the near field's high band enters, ``'additive'`` (``l(S) + h(G)``, the
    paper), ``'multiplicative'`` (``l(S) G / l(G)``), ``'ratio'`` (``l(S) + h(G) l(S) / l(S_c)``, with
    ``far_capture`` the far field under the capture light; None: the render light is the capture light) or
    ``'residual'`` (``S + l(S) (h(G) / l(G) - h(S_c) / l(S_c))``), see :mod:`pgc.filtering.detail`."""
    if silhouette not in ("near", "far"):
        raise ValueError(f"compose: silhouette must be 'near' or 'far', not {silhouette!r}")
    g, s = unpremultiply(near), unpremultiply(far)
    low_near = filt.lowpass(g, near.alpha, kernel_size)
    high = g - low_near
    low = filt.lowpass(s, far.alpha, kernel_size)
    a, fa = near.alpha[..., None], far.alpha[..., None]
    low_capture = high_far = high_capture = None
    if detail in CAPTURE_FAR_FIELD_MODES and far_capture is not None:
        s_capture = unpremultiply(far_capture)
        low_capture = filt.lowpass(s_capture, far_capture.alpha, kernel_size)
        high_capture = s_capture - low_capture
    if detail == "residual":
        high_far = s - low
    colour = hybrid_colour(high if silhouette == "near" else a * high, low_near, low, detail, low_capture,
                           high_far, high_capture)
    if silhouette == "far" and outline_fade > 0:
        weight = outline_weight(far.alpha, outline_fade * kernel_size)[..., None]
        colour = s + weight * (colour - s)
    colour = np.clip(colour, 0.0, None)
    shape = a if silhouette == "near" else fa
    bg = np.zeros_like(colour) if background is None else np.broadcast_to(background, colour.shape)

    def over(c: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        return (alpha * c + (1 - alpha) * bg).astype(np.float32)

    return HybridFrame(over(colour, shape), over(g, a), over(s, fa), low, high, near.alpha, shape[..., 0])
