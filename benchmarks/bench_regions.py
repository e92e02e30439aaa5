"""Where is the error of each variant: inside the garment or on its outline, at the capture pose or later?

For evaluated runs (``pgc render`` and ``pgc eval`` done, ground truth from a synthetic capture), splits the
eval's region (true garment coverage or the variant's alpha) into the **interior** (true coverage and the
variant's alpha both above 0.5, eroded by ``--erode`` px) and the **outline** (the rest of the region), and
scores every variant on each part with the run's metrics, per frame and in the mean over runs, frames and
cameras. Frame 0 is the capture pose: a variant that already loses there loses for its appearance, one that
loses only later loses for how it deforms.

    .venv/bin/python benchmarks/bench_regions.py RUN [RUN ...] --gt CAPTURE [--config FILE] [--json OUT.json]

Prints a table and writes JSON records (one per run, variant, frame and part).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

PARTS = ("region", "interior", "outline")


def parts(coverage: np.ndarray, alpha: np.ndarray, erode: int) -> dict[str, np.ndarray]:
    """(H, W) float32 weights of the eval's region (:func:`pgc.pipeline.evaluate.eval_region`) and of its
    interior and outline."""
    from scipy.ndimage import binary_erosion

    from pgc.pipeline.evaluate import eval_region

    region = eval_region(coverage, alpha) > 0
    interior = (coverage > 0.5) & (alpha > 0.5)
    if erode:  # scipy erodes until nothing changes when iterations < 1
        interior = binary_erosion(interior, iterations=erode)
    return {"region": region.astype(np.float32), "interior": interior.astype(np.float32),
            "outline": (region & ~interior).astype(np.float32)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="run folders (rendered and evaluated)")
    parser.add_argument("--gt", required=True, help="the synthetic capture the runs were evaluated against")
    parser.add_argument("--config", help="run config TOML (the metrics; built-in defaults otherwise)")
    parser.add_argument("--erode", type=int, default=3, help="px the interior is eroded by")
    parser.add_argument("--json", help="write the records here")
    args = parser.parse_args()

    from pgc.config import load as load_config
    from pgc.events import Reporter
    from pgc.pipeline.evaluate import VARIANTS, layer_alpha, rendered_frames, synthetic_ground_truth

    cfg = load_config(args.config)
    metrics = cfg.roles["metric"].create_all()
    gt = Path(args.gt)
    records = []
    for run in map(Path, args.runs):
        meta, frames = rendered_frames(run)
        truth = synthetic_ground_truth(run, gt, frames, meta["cameras"], cfg,
                                       Reporter.silent())
        for i, t in enumerate(frames):
            with np.load(run / "render" / f"frame_{t:04d}.npz") as z:
                pred = {k: z[k] for k in z.files}
            coverage = truth[i]["garment_mask"]
            target = truth[i]["color"] * coverage[..., None]
            for variant, layer in VARIANTS.items():
                alpha = pred[layer_alpha(layer, pred)]
                for c in range(len(target)):
                    weights = parts(coverage[c], alpha[c], args.erode)
                    for part, w in weights.items():
                        row = {"run": str(run), "variant": variant, "frame": t, "camera": meta["cameras"][c],
                               "part": part, "pixels": int(w.sum())}
                        for name, metric in metrics.items():
                            row[name] = float(metric(pred[layer][c], target[c], w)) if w.sum() else float("nan")
                        records.append(row)

    def mean(variant: str, part: str, name: str, frame: int | None = None) -> float:
        vals = [r[name] for r in records if r["variant"] == variant and r["part"] == part
                and (frame is None or r["frame"] == frame) and np.isfinite(r[name])]
        return float(np.mean(vals)) if vals else float("nan")

    names = list(metrics)
    frames_seen = sorted({r["frame"] for r in records})
    print(f"{len(args.runs)} runs, frames {frames_seen}; interior eroded by {args.erode} px")
    print("| variant | part | " + " | ".join(names) + " |")
    print("| --- | --- | " + " | ".join("---" for _ in names) + " |")
    for variant in VARIANTS:
        for part in PARTS:
            print(f"| {variant} | {part} | " + " | ".join(f"{mean(variant, part, n):.4f}" for n in names) + " |")
    print("\nLPIPS by frame (interior): " + ", ".join(VARIANTS))
    for t in frames_seen:
        print(f"  frame {t:3d}: " + "  ".join(f"{mean(v, 'interior', 'lpips', t):.4f}" for v in VARIANTS)
              + "   region: " + "  ".join(f"{mean(v, 'region', 'lpips', t):.4f}" for v in VARIANTS))
    if args.json:
        Path(args.json).write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    main()
