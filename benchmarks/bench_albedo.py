#!/usr/bin/env python
"""Albedo estimators and the base-colour texture against the synthetic ground truth.

    python benchmarks/bench_albedo.py CAPTURE ASSET_STAGES [--out bench_albedo.json]

CAPTURE: a `pgc synth` capture (its views carry the ground-truth 'albedo' layer); ASSET_STAGES: the
`stages/` folder of a `pgc reconstruct` run on it (the garment sub-mesh and full mesh come from there).
For each estimator (the raw image used as albedo, the reference; the ONNX network, by default the shipped
one; the model-free `shading_ratio` baseline, fed the white-albedo shading of the reconstructed full mesh
rendered by the configured pbr_renderer, as in `pgc reconstruct`; and the ground-truth albedo layer itself,
the floor that back-projection and merging leave) it reports the per-view albedo error on the garment
(after the best per-channel scale, since albedo is only known up to one), the cross-view spread before
and after colour correction, the error of the merged texture seen through every camera, and seconds
(ratios to the raw reference measured in the same run).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


class RawImage:
    """The image itself as albedo: the reference an estimator must beat."""

    needs_shading = False
    fingerprint = None

    def estimate(self, image, mask=None, shading=None):
        return np.asarray(image, np.float32)


class GroundTruthAlbedo:
    """The capture's ground-truth albedo of the view whose image is passed: the floor of the merged-texture
    error that back-projection and merging leave (mesh and pose errors, resampling, occlusion borders)."""

    needs_shading = False
    fingerprint = None

    def __init__(self, views) -> None:
        self._albedo = {id(v.image): v.extras["albedo"] for v in views}

    def estimate(self, image, mask=None, shading=None):
        return np.asarray(self._albedo[id(image)], np.float32)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("capture", type=Path)
    p.add_argument("stages", type=Path)
    p.add_argument("--out", type=Path, default=Path("bench_albedo.json"))
    p.add_argument("--model", type=Path, default=None, help="ONNX model (default: the shipped one)")
    p.add_argument("--shading-kernel", type=int, nargs="*", default=None, metavar="K",
                   help="onnx runs with these shading_kernel settings (px; 0 = raw prediction; default: the option's)")
    p.add_argument("--skip", nargs="*", default=[], choices=["onnx", "shading_ratio"])
    p.add_argument("--camera-casts", type=float, default=0.0, metavar="G",
                   help="multiply each view by random per-channel gains in [1 - G, 1 + G] (seeded): uncalibrated "
                        "cameras' exposure and white balance, what colour correction is there to remove")
    args = p.parse_args(argv)

    from pgc import config
    from pgc.albedo.dataset import scale_invariant_error
    from pgc.albedo.shading_ratio import ShadingRatioEstimator
    from pgc.albedo.base_color import build_base_color, garment_mask
    from pgc.io.capture import read_capture
    from pgc.pipeline.reconstruct import white_shading
    from pgc.pipeline.stage_io import load_mesh
    from pgc.texture.visibility import render_texture_to_view
    from pgc_onnx.albedo import OnnxAlbedoEstimator

    capture = read_capture(args.capture)
    rng = np.random.default_rng(0)
    for v in capture.views:
        if args.camera_casts > 0:
            v.image = v.image * rng.uniform(1 - args.camera_casts, 1 + args.camera_casts, 3).astype(np.float32)
    full = load_mesh(args.stages / "mesh" / "mesh.npz")
    garment = load_mesh(args.stages / "garment" / "garment.npz")
    ids = capture.garment_label_ids
    render_shading = white_shading(config.load(None), full)
    shadings: dict[str, np.ndarray] = {}

    def shading(view):
        """The view's white-albedo shading, rendered once (its time counts in the first estimator using it)."""
        if view.camera.name not in shadings:
            shadings[view.camera.name] = render_shading(view)
        return shadings[view.camera.name]

    estimators = [("ground_truth", GroundTruthAlbedo(capture.views)), ("raw_image", RawImage())]
    if "onnx" not in args.skip:
        model = {"model": str(args.model) if args.model else None}
        for k in args.shading_kernel if args.shading_kernel is not None else [None]:
            estimators.append(("onnx" if k is None else f"onnx_k{k}",
                               OnnxAlbedoEstimator(model if k is None else {**model, "shading_kernel": k})))
    if "shading_ratio" not in args.skip:
        estimators.append(("shading_ratio", ShadingRatioEstimator()))
    records = []
    for name, estimator in estimators:
        start = time.perf_counter()
        shade = shading if estimator.needs_shading else None
        per_view = [scale_invariant_error(estimator.estimate(v.image, garment_mask(v, ids),
                                                             shade(v) if shade else None),
                                          v.extras["albedo"], garment_mask(v, ids)) for v in capture.views]
        res = build_base_color(capture, garment, estimator, 512, 10, occluder=full, shading=shade)
        seconds = time.perf_counter() - start
        merged = []
        for v in capture.views:
            tex, cover = render_texture_to_view(garment, res.texture, v.camera)
            merged.append(scale_invariant_error(tex, v.extras["albedo"], garment_mask(v, ids) * cover))
        records.append({"role": "albedo_estimator", "implementation": name, "preset": str(args.capture),
                        "camera_casts": args.camera_casts, "seconds": seconds,
                        "errors": {"albedo_view": float(np.mean(per_view)), "albedo_view_std": float(np.std(per_view)),
                                   "texture": float(np.mean(merged)), "texture_std": float(np.std(merged)),
                                   "spread_before": res.figures["spread_before_correction"],
                                   "spread_after": res.figures["spread_after_correction"]}})
    ref = records[1]["seconds"]
    print(f"{'estimator':<13} {'x raw':>6} {'view err':>9} {'texture err':>12} {'spread before':>14} {'after':>7}")
    for r in records:
        e = r["errors"]
        r["x_reference"] = r["seconds"] / ref
        print(f"{r['implementation']:<13} {r['x_reference']:6.2f} {e['albedo_view']:9.4f} {e['texture']:12.4f} "
              f"{e['spread_before']:14.4f} {e['spread_after']:7.4f}")
    args.out.write_text(json.dumps(records, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
