"""The report's pictures: garment crops enlarged with nearest-neighbour, error heatmaps, animated WebP loops,
and matplotlib charts (SVG). Renders and ground truth are linear RGB over black; every picture is written
sRGB-encoded, atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pgc.io.atomic import atomic_path, write_text
from pgc.io.images import linear_to_srgb

CROP_TARGET = 240
"""Displayed height (px) the garment crop is enlarged to, by an integer nearest-neighbour factor."""
CROP_PAD = 4
"""Pixels kept around the garment's bounding box."""
ERROR_MAX = 0.25
"""Linear-RGB absolute error (mean over channels) shown at the top of the heatmap colour scale."""
DETAIL_SIZE = 40
"""Edge (px) of a detail window: small enough to enlarge 5x, large enough to hold a pocket edge or a few ribs."""
DETAIL_TARGET = 200
"""Displayed edge (px) a detail window is enlarged to."""


def garment_box(coverages: list[np.ndarray], pad: int = CROP_PAD) -> tuple[int, int, int, int]:
    """(row0, row1, col0, col1) bounding the pixels where any of ``coverages`` (H, W) exceeds 0.01,
    padded by ``pad`` and clipped to the image; the whole image when nothing is covered."""
    union = np.any([np.asarray(c) > 0.01 for c in coverages], axis=0)
    h, w = union.shape
    if not union.any():
        return 0, h, 0, w
    rows, cols = np.nonzero(union.any(1))[0], np.nonzero(union.any(0))[0]
    return (max(rows[0] - pad, 0), min(rows[-1] + 1 + pad, h), max(cols[0] - pad, 0), min(cols[-1] + 1 + pad, w))


def detail_windows(image: np.ndarray, inside: np.ndarray, size: int = DETAIL_SIZE, count: int = 2,
                   band: tuple[float, float] = (1.0, 3.0)) -> list[tuple[int, int, int, int]]:
    """Up to ``count`` non-overlapping ``size`` x ``size`` boxes (row0, row1, col0, col1) of ``image`` (H, W, 3)
    that hold the most fine structure: the largest sums of the band-pass energy ``|G_a * image - G_b * image|^2``
    (Gaussian blurs of standard deviations ``band`` = (a, b) px, mean over channels: ribs, seams and edges a few
    pixels wide, not pixel noise) among windows lying wholly where ``inside`` (H, W, bool) is true, on a grid of
    half a window; greedily, best first. Empty when no window fits inside."""
    from scipy.ndimage import gaussian_filter

    img = np.nan_to_num(np.asarray(image, np.float64))
    high = ((gaussian_filter(img, (band[0], band[0], 0)) - gaussian_filter(img, (band[1], band[1], 0))) ** 2).mean(-1)
    h, w = high.shape
    if h < size or w < size:
        return []

    def window_sums(a: np.ndarray) -> np.ndarray:  # sums of every size x size window, by the integral image
        c = np.pad(np.cumsum(np.cumsum(a, 0), 1), ((1, 0), (1, 0)))
        return c[size:, size:] - c[:-size, size:] - c[size:, :-size] + c[:-size, :-size]

    energy = window_sums(high)
    full = window_sums(np.asarray(inside, np.float64)) >= size * size - 0.5
    step = max(1, size // 2)
    candidates = sorted(((float(energy[y, x]), y, x) for y in range(0, h - size + 1, step)
                         for x in range(0, w - size + 1, step) if full[y, x]), reverse=True)
    chosen: list[tuple[int, int, int, int]] = []
    for _, y, x in candidates:
        if len(chosen) == count:
            break
        if all(y + size <= a or b <= y or x + size <= c or d <= x for a, b, c, d in chosen):
            chosen.append((y, y + size, x, x + size))
    return chosen


def enlarge_factor(box: tuple[int, int, int, int], target: int = CROP_TARGET) -> int:
    """Integer nearest-neighbour factor that brings the crop's height near ``target`` px (at least 1)."""
    return max(1, int(round(target / max(box[1] - box[0], 1))))


def crop(image: np.ndarray, box: tuple[int, int, int, int], factor: int) -> np.ndarray:
    """``image`` (H, W[, C]) cut to ``box`` and enlarged ``factor`` times by pixel repetition."""
    part = np.asarray(image)[box[0]:box[1], box[2]:box[3]]
    return np.repeat(np.repeat(part, factor, axis=0), factor, axis=1)


def to_rgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB (H, W, 3) -> sRGB uint8 (clipped to [0, 1])."""
    return np.rint(linear_to_srgb(np.nan_to_num(linear)) * 255).astype(np.uint8)


def heatmap_rgb8(pred: np.ndarray, target: np.ndarray, vmax: float = ERROR_MAX) -> np.ndarray:
    """|pred - target| (mean over channels, linear RGB) in matplotlib's 'inferno' from 0 to ``vmax``, uint8."""
    from matplotlib import colormaps

    err = np.abs(np.asarray(pred, np.float64) - np.asarray(target, np.float64)).mean(-1)
    return (colormaps["inferno"](np.clip(err / vmax, 0, 1))[..., :3] * 255).round().astype(np.uint8)


def save_png(path: Path, rgb8: np.ndarray) -> None:
    from PIL import Image

    with atomic_path(path) as tmp:
        Image.fromarray(np.ascontiguousarray(rgb8)).save(tmp, format="PNG", optimize=True)


def save_webp_loop(path: Path, frames: list[np.ndarray], frame_ms: int) -> None:
    """An endlessly looping animated WebP (lossless) of uint8 RGB ``frames``."""
    from PIL import Image

    images = [Image.fromarray(np.ascontiguousarray(f)) for f in frames]
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="WEBP", save_all=True, append_images=images[1:], duration=frame_ms, loop=0,
                       lossless=True)


def side_by_side(*images: np.ndarray, gap: int = 4) -> np.ndarray:
    """uint8 images of one height joined left to right with a white ``gap``."""
    h = images[0].shape[0]
    parts = []
    for i, im in enumerate(images):
        if i:
            parts.append(np.full((h, gap, 3), 255, np.uint8))
        parts.append(im)
    return np.concatenate(parts, axis=1)


def _save_svg(fig, path: Path) -> None:
    import io

    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight")
    write_text(path, buf.getvalue())


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 9, "svg.fonttype": "none", "axes.spines.top": False,
                         "axes.spines.right": False})
    return plt


VARIANT_COLOURS = {"hybrid": "#1b7837", "3dgs_only": "#7b3294", "pbr_only": "#e08214"}
HIGHER_IS_BETTER = {"psnr": True, "psnr-exposure": True, "ssim": True, "fsim": True, "lpips": False}


def metrics_chart(path: Path, per_motion: dict[str, dict[str, dict[str, float]]]) -> None:
    """Grouped bars: one panel per metric, motions on x, one bar per variant."""
    plt = _pyplot()
    motions = list(per_motion)
    variants = list(next(iter(per_motion.values())))
    names = list(next(iter(per_motion.values()))[variants[0]])
    fig, axes = plt.subplots(1, len(names), figsize=(2.6 * len(names), 2.6), squeeze=False)
    x = np.arange(len(motions))
    width = 0.8 / len(variants)
    for ax, name in zip(axes[0], names):
        for i, v in enumerate(variants):
            ax.bar(x + (i - (len(variants) - 1) / 2) * width, [per_motion[m][v][name] for m in motions], width,
                   label=v, color=VARIANT_COLOURS.get(v))
        better = {True: "higher is better", False: "lower is better"}.get(HIGHER_IS_BETTER.get(name), "")
        ax.set_title(f"{name.upper()} ({better})" if better else name.upper())
        ax.set_xticks(x, motions)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(variants), frameon=False, bbox_to_anchor=(0.5, 1.0))
    _save_svg(fig, path)
    plt.close(fig)


def timings_chart(path: Path, groups: dict[str, dict[str, float]], label: str) -> None:
    """Horizontal bars, one panel per group (title -> {step: seconds}), measured here; ``label`` under titles."""
    plt = _pyplot()
    groups = [(t, d) for t, d in groups.items() if d]
    fig, axes = plt.subplots(1, len(groups), figsize=(4.2 * len(groups), 0.35 * max(len(d) for _, d in groups) + 1),
                             squeeze=False)
    for ax, (title, data) in zip(axes[0], groups):
        labels = list(data)[::-1]
        ax.barh(labels, [data[k] for k in labels], color="#4575b4")
        for i, k in enumerate(labels):
            ax.text(data[k], i, f" {data[k]:.1f}", va="center", fontsize=8)
        ax.set_xlim(0, 1.2 * max(max(data.values()), 1e-9))
        ax.set_xlabel("seconds")
        ax.set_title(f"{title}\n{label}")
    _save_svg(fig, path)
    plt.close(fig)


def bench_chart(path: Path, records: list[dict[str, Any]]) -> bool:
    """Speed against error from ``pgc bench`` records: one log-log panel per role (seconds vs the role's
    plotted error). Returns False (and writes nothing) when no record has both."""
    plt = _pyplot()
    by_role: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        err = (r.get("errors") or {}).get(r.get("error_key") or "")
        if isinstance(r.get("seconds"), (int, float)) and isinstance(err, (int, float)) and r["seconds"] > 0 \
                and err > 0 and np.isfinite(err):
            by_role.setdefault(r["role"], []).append({**r, "_error": float(err)})
    if not by_role:
        return False
    fig, axes = plt.subplots(1, len(by_role), figsize=(3.2 * len(by_role), 3.0), squeeze=False)
    for ax, (role, rows) in zip(axes[0], sorted(by_role.items())):
        for r in rows:
            ax.scatter(r["seconds"], r["_error"], s=18)
            ax.annotate(r.get("label") or r.get("implementation", ""), (r["seconds"], r["_error"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(role)
        ax.set_xlabel("seconds (lower is faster)")
        ax.set_ylabel(rows[0].get("error_key", "error"))
    _save_svg(fig, path)
    plt.close(fig)
    return True


def colourbar_svg(path: Path, vmax: float = ERROR_MAX) -> None:
    """The heatmaps' colour scale."""
    plt = _pyplot()
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig, ax = plt.subplots(figsize=(3.2, 0.45))
    fig.colorbar(ScalarMappable(Normalize(0, vmax), "inferno"), cax=ax, orientation="horizontal",
                 label="|render - ground truth| (linear RGB, mean of channels)")
    _save_svg(fig, path)
    plt.close(fig)
