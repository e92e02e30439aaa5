"""``pgc demo``: the whole pipeline on a synthetic scene."""

from __future__ import annotations

import argparse

from pgc.commands._common import check_out_folder, emit, reporter_for, writing


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="the whole pipeline on the default synthetic scene",
        description="Generate a synthetic capture with ground truth, reconstruct the garment asset, simulate "
                    "it on the paper's three test motions (goalpost, spooky, arms-up), render the hybrid and "
                    "the ablations, render the ground truth on the same simulated geometry, and evaluate. "
                    "Writes OUT/metrics.json and OUT/report.html. Cached: a rerun resumes.",
        epilog="presets: tiny (minutes; for tests), default (the demo scene, 64 views at 256 px)")
    p.add_argument("--preset", default="default", choices=("tiny", "default"), help="scene and settings preset")
    p.add_argument("--out", default=None, help="output folder (default runs/demo-PRESET)")
    p.add_argument("--config", metavar="FILE", help="config TOML merged over the preset's settings")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic scene")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.demo import run_demo
    from pgc.pipeline.evaluate import VARIANTS

    out = check_out_folder(args.out or f"runs/demo-{args.preset}")
    registry, reporter = reporter_for(args)
    with writing(out, "pgc demo"):
        summary = run_demo(out, args.preset, args.config, seed=args.seed, reporter=reporter, registry=registry)
    lines = [f"{v:>10}: " + "  ".join(f"{k}={x:.4f}" for k, x in summary[v].items()) for v in VARIANTS]
    emit(args, summary, "\n".join(lines) + f"\nreport: {out}/report.html")
    return 0
