"""``pgc eval``: metrics of a rendered run against ground truth."""

from __future__ import annotations

import argparse

from pgc.commands._common import (add_run_options, check_out_file, check_run, emit, load_config, reporter_for,
                                  writing)


def add_parser(sub: argparse._SubParsersAction) -> None:
    from pgc.stages.eval import MODES

    p = sub.add_parser(
        "eval", help="metrics of a run against ground truth",
        description="Compare the rendered frames of a run with ground truth: PSNR, SSIM, FSIM and LPIPS (the "
                    "configured metrics) of the hybrid render and of the 3DGS-only and PBR-only ablations, per "
                    "frame and mean, on the garment region. --gt is a synthetic capture (its ground truth is "
                    "rendered on the run's own simulated geometry) or a folder of frame_XXXX_CAMERA.png images.",
        epilog="example: pgc eval runs/spooky --gt runs/capture --out spooky_metrics.json")
    p.add_argument("run", help="run folder (rendered with pgc render)")
    p.add_argument("--gt", required=True, help="synthetic capture folder or image folder")
    p.add_argument("--out", help="metrics JSON path (default RUN/metrics.json)")
    p.add_argument("--mode", choices=MODES, default=MODES[0],
                   help="ground truth on the run's simulated geometry (appearance, default; refused for a run that "
                        "moved on the body fitted to the capture) or simulated on its own on the capture's true body "
                        "(independent: the paper's comparison; the run may move on the fitted body, see "
                        "'pgc reconstruct --body fit')")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pgc.errors import PGCDataError
    from pgc.pipeline.evaluate import VARIANTS, evaluate_run, rendered_frames

    check_run(args.run)
    rendered_frames(Path(args.run))
    if args.out:
        check_out_file(args.out)
    if not Path(args.gt).is_dir():
        raise PGCDataError(f"--gt {args.gt}: not a folder; give a synthetic capture folder or a folder of "
                           "frame_XXXX_CAMERA.png images")
    registry, reporter = reporter_for(args)
    cfg = load_config(args, registry)
    with writing(args.run, "pgc eval"):
        res = evaluate_run(args.run, args.gt, cfg, reporter, args.out, args.mode, registry)
    lines = [f"{v:>10}: " + "  ".join(f"{k}={x:.4f}" for k, x in res[v].items() if k != "per_frame")
             for v in VARIANTS]
    emit(args, res, f"mode: {args.mode}\n" + "\n".join(lines))
    return 0
