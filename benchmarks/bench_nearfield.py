"""Does the near field generalise? Garment-interior PSNR at the capture pose on training and held-out views.

For an asset and the capture it was reconstructed from, renders every capture view (or ``--max-views`` of each
kind) at the rest shape under the fitted capture light, with the body hiding the garment where it is in front:
the near field alone (the Gaussians, 3DGS-only), the PBR render of the mesh (PBR-only) and the hybrid (with the
kernel rule's decision on the held-out views, as ``pgc render`` takes it). Scores: linear and sRGB PSNR over the
garment interior (the garment segmentation eroded by ``--erode`` px), split into the views the splat fit trained
on and those it held out (``asset.heldout_views``). A near field that generalises scores about the same on both.

    .venv/bin/python benchmarks/bench_nearfield.py ASSET CAPTURE [--config FILE] [--json OUT.json]

Prints a table and writes JSON records (one per variant and split).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("asset", help="asset folder (pgc reconstruct)")
    parser.add_argument("capture", help="the capture folder the asset was reconstructed from")
    parser.add_argument("--config", help="run config TOML (the asset's roles by default)")
    parser.add_argument("--erode", type=int, default=2, help="px the garment segmentation is eroded by")
    parser.add_argument("--max-views", type=int, default=8, help="views per split at most (evenly spread)")
    parser.add_argument("--json", help="write the records here")
    args = parser.parse_args()

    from scipy.ndimage import binary_erosion

    from pgc.albedo.base_color import garment_mask
    from pgc.config import load as load_config
    from pgc.io.asset import read_asset
    from pgc.io.capture import read_capture
    from pgc.metrics.psnr import psnr
    from pgc.pipeline.compose import compose
    from pgc.pipeline.garment import body_occluder
    from pgc.pipeline.render import HybridRenderer, choose_kernel
    from pgc.sampling import spread

    asset, capture = read_asset(args.asset), read_capture(args.capture)
    cfg = load_config(args.config)
    renderer = HybridRenderer(asset, cfg)
    decision = choose_kernel(renderer, capture, cfg)
    body = body_occluder(asset.body, capture.garment_label_ids)
    held = set(asset.heldout_views)
    splits = {"train": spread([v for v in capture.views if v.camera.name not in held], args.max_views),
              "heldout": spread([v for v in capture.views if v.camera.name in held], args.max_views)}
    records = []
    start = time.perf_counter()
    for split, views in splits.items():
        scores: dict[str, dict[str, list[float]]] = {k: {"linear": [], "srgb": []} for k in ("near", "pbr", "hybrid")}
        for view in views:
            lay = renderer.layers(asset.garment.vertices, view.camera, asset.light, decision.far_source, body)
            h = compose(lay["near"], lay["far"], renderer.filter, decision.kernel_size,
                        silhouette=renderer.settings.silhouette, outline_fade=renderer.settings.outline_fade)
            interior = binary_erosion(garment_mask(view, capture.garment_label_ids) > 0.5, iterations=args.erode)
            if not interior.any():
                continue
            mask = interior.astype(np.float64)
            for name, image in (("near", lay["near"].color), ("pbr", lay["pbr"].color), ("hybrid", h.hybrid)):
                for space in ("linear", "srgb"):
                    scores[name][space].append(psnr(image, view.image, mask, color_space=space))
        for name, by_space in scores.items():
            records.append({"variant": name, "split": split, "views": len(by_space["linear"]),
                            "psnr_linear": float(np.mean(by_space["linear"])) if by_space["linear"] else None,
                            "psnr_srgb": float(np.mean(by_space["srgb"])) if by_space["srgb"] else None})
    print(f"asset {args.asset}: kernel {decision.kernel_size} px, far field {decision.far_source}, "
          f"{len(asset.gaussians)} Gaussians (SH {asset.gaussians.sh_degree}), {time.perf_counter() - start:.0f} s")
    print(f"{'variant':8} {'split':8} {'views':>5} {'PSNR linear':>12} {'PSNR sRGB':>10}")
    for r in records:
        lin = "-" if r["psnr_linear"] is None else f"{r['psnr_linear']:.2f}"
        srgb = "-" if r["psnr_srgb"] is None else f"{r['psnr_srgb']:.2f}"
        print(f"{r['variant']:8} {r['split']:8} {r['views']:>5} {lin:>12} {srgb:>10}")
    if args.json:
        Path(args.json).write_text(json.dumps({"asset": str(args.asset), "kernel": decision.to_json(),
                                               "records": records}, indent=2))


if __name__ == "__main__":
    main()
