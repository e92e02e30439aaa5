"""The base-colour texture stage (docs/method.md, section 3): per-view albedo -> colour correction -> UV merge.

1. choose the views that together see most of the garment (greedy coverage, ``num_views``, paper: 10);
2. predict albedo per view with the configured ``albedo_estimator``;
3. colour correction (robust least squares, :mod:`pgc.texture.color_correction`): per view a 3x3 matrix
   mapping its prediction onto the views' consensus (the weighted median of the raw back-projections)
   over the texels it sees, which normalises colour and scale across views; then one global 3x3 matrix
   mapping the normalised prediction towards the images inside the garment masks (the paper's "towards
   the image"), which puts the albedo in the capture's colour space;
4. back-project the corrected albedo into the UV atlas with visibility (the full mesh occludes),
   weight by viewing angle and footprint, merge by a weighted median, fill holes and pad seams.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from pgc.events import Reporter
from pgc.roles.albedo_estimator import AlbedoEstimator
from pgc.texture.atlas import texel_geometry
from pgc.texture.backproject import ViewTexture, fill_holes, merge_views, project_view
from pgc.texture.color_correction import apply_color_matrix, fit_color_matrix
from pgc.types import Capture, Mesh, View


@dataclass
class BaseColorResult:
    texture: np.ndarray
    """(H, W, 3) float32 linear base colour over the garment's UV atlas (holes filled, seams padded)."""
    coverage: np.ndarray
    """(H, W) float32 merged view weight per texel (0: filled, not observed)."""
    figures: dict[str, Any] = field(default_factory=dict)


def garment_mask(view: View, garment_ids: list[int]) -> np.ndarray:
    """(H, W) float32 1 where the view's segmentation is a garment label (falls back to the mask)."""
    if view.segmentation is not None:
        return np.isin(view.segmentation, garment_ids).astype(np.float32)
    if view.mask is not None:
        return view.mask
    return np.ones(view.image.shape[:2], np.float32)


def cross_view_spread(textures: list[ViewTexture]) -> float:
    """Mean over texels seen by >= 2 views of the weighted std across views divided by the weighted mean
    (a scale-free measure of how much the views disagree)."""
    c = np.stack([t.color for t in textures]).astype(np.float64)
    w = np.stack([t.weight for t in textures]).astype(np.float64)
    seen2 = (w > 0).sum(0) >= 2
    if not seen2.any():
        return float("nan")
    wt = w[:, seen2][..., None]
    cs = c[:, seen2]
    mean = (wt * cs).sum(0) / wt.sum(0)
    std = np.sqrt((wt * (cs - mean) ** 2).sum(0) / wt.sum(0))
    return float(np.mean(std.mean(-1) / np.maximum(mean.mean(-1), 1e-6)))


def build_base_color(capture: Capture, garment: Mesh, estimator: AlbedoEstimator, texture_size: int = 512,
                     num_views: int = 10, occluder: Mesh | None = None,
                     shading: Callable[[View], np.ndarray] | None = None,
                     reporter: Reporter | None = None) -> BaseColorResult:
    """Merge per-view albedo predictions into the UV atlas of ``garment``.

    ``occluder``: the full reconstructed mesh (hides garment texels behind the body); ``shading``: a
    function giving a view's white-albedo shading, for estimators that need it (``shading_ratio``).
    """
    reporter = reporter or Reporter.silent()
    ids = capture.garment_label_ids
    with reporter.stage("base_color", total=len(capture.views) + num_views) as st:
        geom = texel_geometry(garment, texture_size, texture_size)
        masks = [garment_mask(v, ids) for v in capture.views]
        # Visibility/weights per view on the images themselves (cheap), for view selection.
        probes = []
        for i, (view, mask) in enumerate(zip(capture.views, masks)):
            probes.append(project_view(geom, garment, view.camera, view.image, mask, occluder=occluder))
            st.progress(i + 1)
        chosen = _greedy_views([p.weight for p in probes], num_views)
        albedos, raw = [], []
        for k, i in enumerate(chosen):
            view, mask = capture.views[i], masks[i]
            albedos.append(estimator.estimate(view.image, mask, shading(view) if shading is not None else None))
            raw.append(project_view(geom, garment, view.camera, albedos[-1], mask, occluder=occluder))
            st.progress(len(capture.views) + k + 1)
        consensus, seen_any = merge_views(raw, "median")
        matrices = [fit_color_matrix(r.color[seen_any > 0], consensus[seen_any > 0], r.weight[seen_any > 0])
                    for r in raw]
        inside = [masks[i] > 0.5 for i in chosen]
        pairs_src = np.concatenate([apply_color_matrix(a[m], mv) for a, m, mv in zip(albedos, inside, matrices)])
        pairs_dst = np.concatenate([capture.views[i].image[m] for i, m in zip(chosen, inside)])
        to_image = fit_color_matrix(pairs_src, pairs_dst)
        # bilinear sampling is linear, so correcting the back-projected colours equals back-projecting the
        # corrected images
        normalised = [ViewTexture(apply_color_matrix(r.color, mv), r.weight) for r, mv in zip(raw, matrices)]
        corrected = [ViewTexture(apply_color_matrix(r.color, to_image), r.weight) for r in normalised]
        merged, weight = merge_views(corrected, "median")
        seen = weight > 0
        texture = fill_holes(merged, seen)
        figures = {
            "views": [capture.views[i].camera.name for i in chosen],
            "texture_size": texture_size,
            "atlas_fill": float(geom.valid.mean()),
            "observed_fraction": float(seen.sum() / max(geom.valid.sum(), 1)),
            "spread_before_correction": cross_view_spread(raw),
            "spread_after_correction": cross_view_spread(normalised),
            "color_matrices": [m.tolist() for m in matrices],
            "to_image_matrix": to_image.tolist(),
        }
        st.record(**{k: v for k, v in figures.items() if isinstance(v, float)})
    return BaseColorResult(texture, weight, figures)


def _greedy_views(weights: list[np.ndarray], count: int) -> list[int]:
    """Pick up to ``count`` views greedily maximising the summed best weight per texel (coverage)."""
    best = np.zeros_like(weights[0], dtype=np.float64)
    chosen: list[int] = []
    for _ in range(min(count, len(weights))):
        gains = [-1.0 if i in chosen else float(np.maximum(best, w).sum() - best.sum())
                 for i, w in enumerate(weights)]
        i = int(np.argmax(gains))
        if gains[i] <= 0 and chosen:
            break
        chosen.append(i)
        best = np.maximum(best, weights[i])
    return chosen
