#!/usr/bin/env python
"""Train the shipped albedo network on synthetic renders and export it to ONNX (seeded, reproducible).

    python scripts/train_albedo.py                 # the shipped model (~20 min on 2 quiet cores)
    python scripts/train_albedo.py --smoke --out /tmp/m.onnx   # seconds: a pipeline check

Writes the model (default plugins/pgc_onnx/models/albedo_unet.onnx) and beside it a JSON record: settings,
data sizes, validation errors on held-out garments (network vs the raw image used as albedo), the
model's sha256. Rendered training data is cached under .cache/ keyed by its settings.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "plugins" / "pgc_onnx" / "models" / "albedo_unet.onnx"


DATA_VERSION = 3
"""Bumped when pgc.synth.albedo_data changes what it renders (the cache key)."""


def cached_data(kind: str, scenes: int, views: int, resolution: int, seed: int, spp: int, cfg, reporter):
    """The training data of these settings rendered by ``cfg``'s scene renderer (cached under .cache/, keyed by the
    settings and the renderer's implementation, options and version)."""
    from pgc.albedo.dataset import AlbedoData
    from pgc.pipeline.cache import content_key
    from pgc.synth.albedo_data import make_albedo_data
    from pgc.synth.render import scene_renderer

    renderer_key = content_key("albedo-data-renderer", cfg.role_key("scene_renderer"))[:12]
    path = ROOT / ".cache" / (f"albedo_v{DATA_VERSION}_{kind}_{scenes}x{views}_{resolution}px_{spp}spp_seed{seed}_"
                              f"{renderer_key}.npz")
    if path.is_file():
        with np.load(path) as z:
            return AlbedoData(z["images"], z["albedo"], z["mask"], z["garment"])
    data = make_albedo_data(kind, scenes, views, resolution, seed, spp=spp, reporter=reporter,
                            renderer=scene_renderer(cfg), body_model=cfg.create("body_model"))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, images=data.images, albedo=data.albedo, mask=data.mask, garment=data.garment)
    return data


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scenes", type=int, default=40, help="training scenes (tshirt)")
    p.add_argument("--val-scenes", type=int, default=6, help="validation scenes (dress, never trained on)")
    p.add_argument("--views", type=int, default=6)
    p.add_argument("--resolution", type=int, default=256, help="image side, pixels (the default capture's)")
    p.add_argument("--spp", type=int, default=16, help="path-tracing samples per pixel (low-discrepancy)")
    p.add_argument("--steps", type=int, default=1200)
    p.add_argument("--batch", type=int, default=8)
    p.add_argument("--crop", type=int, default=96)
    p.add_argument("--smoke", action="store_true", help="tiny data and few steps (tests)")
    p.add_argument("--config", type=Path, help="run configuration TOML: its [scene_renderer] renders the data")
    args = p.parse_args(argv)
    if args.smoke:
        args.scenes, args.val_scenes, args.views, args.resolution, args.steps = 1, 1, 2, 48, 5

    import torch

    from pgc.config import load
    from pgc.events import Reporter
    from pgc.progress import ProgressPrinter
    from pgc.registry import Registry
    from pgc_onnx.albedo import OnnxAlbedoEstimator
    from pgc_torch.albedo.net import export_onnx
    from pgc_torch.albedo.train import TrainSettings, evaluate, train

    torch.set_num_threads(2)
    registry = Registry()
    registry.plugin_manager.register(ProgressPrinter(), name="progress")
    reporter = Reporter(registry.hook)
    cfg = load(args.config)
    start = time.perf_counter()
    train_data = cached_data("tshirt", args.scenes, args.views, args.resolution, args.seed, args.spp, cfg, reporter)
    val_data = cached_data("dress", args.val_scenes, args.views, args.resolution, args.seed + 1000, args.spp,
                           cfg, reporter)
    settings = TrainSettings(steps=args.steps, batch=args.batch, crop=args.crop, seed=args.seed)
    data_seconds = time.perf_counter() - start
    model = train(train_data, settings, reporter)
    train_seconds = time.perf_counter() - start - data_seconds
    args.out.parent.mkdir(parents=True, exist_ok=True)
    export_onnx(model, str(args.out), {"pgc_training": f"scripts/train_albedo.py seed={args.seed}"})
    estimator = OnnxAlbedoEstimator({"model": str(args.out)})  # with its default shading smoothing
    val = evaluate(estimator.estimate, val_data)
    train_metrics = evaluate(estimator.estimate, train_data)
    network_only = OnnxAlbedoEstimator({"model": str(args.out), "shading_kernel": 0})
    val_network = evaluate(network_only.estimate, val_data)
    record = {"model": args.out.name, "sha256": hashlib.sha256(args.out.read_bytes()).hexdigest(),
              "bytes": args.out.stat().st_size, "parameters": int(sum(p.numel() for p in model.parameters())),
              "settings": asdict(settings), "data": {"train": {"garment": "tshirt", "images": len(train_data)},
                                                     "validation": {"garment": "dress", "images": len(val_data)},
                                                     "resolution": args.resolution, "views": args.views,
                                                     "spp": args.spp, "data_version": DATA_VERSION},
              "shading_kernel": estimator.options.shading_kernel,
              "validation": val, "validation_network_only": val_network, "training": train_metrics,
              "seconds": {"data": round(data_seconds, 1), "train": round(train_seconds, 1)}}
    args.out.with_suffix(".json").write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps({"validation": val, "seconds": record["seconds"]}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
