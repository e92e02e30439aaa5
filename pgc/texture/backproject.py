"""Back-projection of views into a UV atlas, robust merging across views, hole filling and seam padding."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.texture.atlas import TexelGeometry
from pgc.texture.sample import sample_bilinear
from pgc.texture.visibility import render_faces, visible_points
from pgc.types import Camera, Mesh


@dataclass
class ViewTexture:
    color: np.ndarray
    """(H, W, C) the view's colours at the texels it sees (0 elsewhere)."""
    weight: np.ndarray
    """(H, W) confidence: 0 where unseen; cos(view angle) x footprint x mask elsewhere."""


def project_view(geom: TexelGeometry, mesh: Mesh, camera: Camera, image: np.ndarray,
                 mask: np.ndarray | None = None, vertices: np.ndarray | None = None,
                 min_cos: float = 0.1, occluder: Mesh | None = None) -> ViewTexture:
    """Colours of ``image`` seen by ``camera`` at every texel of ``geom`` (visibility by z-buffer).

    Weight = cos(angle between normal and direction to the camera) (texels seen under a grazing angle
    below ``min_cos`` are dropped) x pixel footprint (f / z)^2 normalised to the view's maximum, x mask.
    ``occluder``: a mesh containing this one (e.g. the full body mesh around a garment) whose z-buffer
    decides visibility, so that the body hides garment texels behind it.
    """
    h, w = geom.face.shape
    valid = geom.valid.reshape(-1)
    pts = geom.position.reshape(-1, 3)[valid]
    fids = geom.face.reshape(-1)[valid]
    if occluder is None:
        seen, xy = visible_points(pts, fids, render_faces(mesh, camera, vertices), camera)
    else:
        seen, xy = visible_points(pts, None, render_faces(occluder, camera), camera)
    to_cam = camera.center - pts
    dist = np.linalg.norm(to_cam, axis=1)
    cos = np.einsum("ij,ij->i", geom.normal.reshape(-1, 3)[valid], to_cam) / np.maximum(dist, 1e-12)
    z = (pts @ camera.R.T + camera.t)[:, 2]
    footprint = (camera.fx / np.maximum(z, 1e-9)) ** 2
    weight = np.where(seen & (cos >= min_cos), cos * footprint / max(footprint.max(initial=0.0), 1e-12), 0.0)
    if mask is not None:
        weight *= sample_bilinear(np.asarray(mask, np.float64)[..., None], xy)[:, 0]
    colors = np.zeros((len(pts), image.shape[2]))
    idx = weight > 0
    colors[idx] = sample_bilinear(np.asarray(image, np.float64), xy[idx])
    out_c = np.zeros((h * w, image.shape[2]))
    out_w = np.zeros(h * w)
    out_c[valid], out_w[valid] = colors, weight
    return ViewTexture(out_c.reshape(h, w, -1).astype(np.float32), out_w.reshape(h, w).astype(np.float32))


def merge_views(textures: list[ViewTexture], method: str = "median") -> tuple[np.ndarray, np.ndarray]:
    """Merge per-view textures per texel: weighted ``median`` (robust to a view's outliers) or ``mean``.

    Returns (merged (H, W, C), total weight (H, W)); texels no view sees are 0 with weight 0.
    """
    colors = np.stack([t.color for t in textures]).astype(np.float64)  # (V, H, W, C)
    weights = np.stack([t.weight for t in textures]).astype(np.float64)  # (V, H, W)
    total = weights.sum(0)
    if method == "mean":
        merged = np.einsum("vhw,vhwc->hwc", weights, colors) / np.maximum(total, 1e-12)[..., None]
    elif method == "median":
        merged = np.zeros(colors.shape[1:])
        for c in range(colors.shape[-1]):
            order = np.argsort(colors[..., c], axis=0)
            vals = np.take_along_axis(colors[..., c], order, axis=0)
            cw = np.cumsum(np.take_along_axis(weights, order, axis=0), axis=0)
            k = np.argmax(cw >= 0.5 * total[None], axis=0)
            merged[..., c] = np.take_along_axis(vals, k[None], axis=0)[0]
    else:
        raise ValueError(f"unknown merge method '{method}' (median or mean)")
    merged[total <= 0] = 0.0
    return merged.astype(np.float32), total.astype(np.float32)


def fill_holes(texture: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Fill texels where ``known`` is False by push-pull (a weighted image pyramid).

    Known texels are kept exactly; unknown ones take the smooth average of their surroundings, which also
    pads chart borders so that bilinear lookups near seams do not bleed in black.
    """
    tex = np.asarray(texture, dtype=np.float64)
    w = np.asarray(known, dtype=np.float64)
    if w.sum() == 0:
        return np.zeros_like(texture)
    filled = _push_pull(tex * w[..., None], w)
    return np.where(known[..., None], tex, filled).astype(np.float32)


def _push_pull(premult: np.ndarray, w: np.ndarray) -> np.ndarray:
    h, wid = w.shape
    if (h <= 1 and wid <= 1) or w.min() > 0:
        return premult / np.maximum(w, 1e-12)[..., None]
    ph, pw = h + h % 2, wid + wid % 2
    p = np.pad(premult, ((0, ph - h), (0, pw - wid), (0, 0)))
    q = np.pad(w, ((0, ph - h), (0, pw - wid)))
    p2 = p.reshape(ph // 2, 2, pw // 2, 2, -1).sum((1, 3))
    q2 = q.reshape(ph // 2, 2, pw // 2, 2).sum((1, 3))
    coarse = _push_pull(p2, q2)
    up = np.repeat(np.repeat(coarse, 2, axis=0), 2, axis=1)[:h, :wid]
    fine = premult / np.maximum(w, 1e-12)[..., None]
    return np.where((w > 0)[..., None], fine, up)
