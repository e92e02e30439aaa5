"""``pgc demo``: the whole pipeline on a synthetic scene."""

from __future__ import annotations

import argparse

from pgc.commands._common import check_out_folder, emit, reporter_for, writing


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="the whole pipeline on the default synthetic scene",
        description="Generate a synthetic capture with ground truth, reconstruct the garment asset, simulate "
                    "it on the paper's three test motions (goalpost, spooky, arms-up) and a captured CMU walk "
                    "(cmu:02_01, in place) on the capture's Anny body, render the hybrid and the ablations, render the "
                    "ground truth on the same simulated geometry, and evaluate, under the capture light and, on "
                    "spooky (--relit-motions), under two novel lights (a sky turned 90 degrees and a low key "
                    "light; relit frames and truth in OUT/runs/MOTION/relit/LIGHT). Writes OUT/metrics.json "
                    "(field 'lights': per light, on the relit motions) and OUT/report.html. Cached: a rerun "
                    "resumes.",
        epilog="presets (pgc synth's, with the settings of pgc/presets/demo_PRESET.toml, else demo_default.toml):\n"
               "  tiny     6 views at 64 px, about 30 s; for tests\n"
               "  default  the demo scene: a striped cotton tee (a fibre truth) resting on the body, with seams,\n"
               "           hems, a patch pocket and folds as geometry; 128 views at 192 px framing the garment;\n"
               "           about 30 min the first time; the capture and the truth's frames (about 22 min of\n"
               "           it) are kept ($PGC_CAPTURE_CACHE; 'off' keeps nothing): later demos about 6 min\n"
               "  cotton   the earlier default: the same tee without the detail, loose, 128 views at 256 px of\n"
               "           the whole body (the garment about 90 px tall); about 7-8 min\n"
               "  knit     a rib-knit tee with knit relief and fibre fuzz, 32 views at 320 px of the garment;\n"
               "           about 40 min",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--preset", default="default", choices=("tiny", "default", "cotton", "knit"),
                   help="scene and settings preset (default: default)")
    p.add_argument("--out", default=None, help="output folder (default runs/demo-PRESET)")
    p.add_argument("--config", metavar="FILE", help="config TOML merged over the preset's settings")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic scene")
    p.add_argument("--lights", nargs="+", metavar="LIGHT", default=None,
                   help="lights to evaluate under (default all: capture sky-rot90 low-key); the capture light "
                        "is always evaluated")
    p.add_argument("--relit-motions", nargs="+", metavar="MOTION", default=None,
                   help="motions evaluated under the novel lights too (default: spooky)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.pipeline.demo import demo_config, run_demo
    from pgc.pipeline.evaluate import VARIANTS
    from pgc.pipeline.relight import check_light_names

    out = check_out_folder(args.out or f"runs/demo-{args.preset}")
    registry, reporter = reporter_for(args)
    if args.lights is not None:
        check_light_names(args.lights, "--lights")
    demo_config(args.preset, args.config, registry).check_implementations()  # before the folder is made
    relit = {} if args.relit_motions is None else {"relit_motions": tuple(args.relit_motions)}
    with writing(out, "pgc demo"):
        summary = run_demo(out, args.preset, args.config, seed=args.seed, reporter=reporter, registry=registry,
                           lights=args.lights, **relit)
    lines = [f"{light:>10} {v:>10}: " + "  ".join(f"{k}={x:.4f}" for k, x in res[v].items())
             for light, res in summary["lights"].items() for v in VARIANTS]
    emit(args, summary, "\n".join(lines) + f"\nreport: {out}/report.html")
    return 0
