"""CPU seconds of ``pgc demo`` per stage, for a machine shared with other work (where wall seconds lie).

Runs the demo in this process with an observer of the stage events that records, per stage name, the wall seconds
and the process's CPU seconds (user + system, every thread, and children that finished) between the stage's start
and end; nested stages (``mesh.stereo`` inside ``mesh``) are recorded each. The demo's own steps (synth,
reconstruct, animate, render, eval, and their relit counterparts) are recorded the same way. Quiet wall time is
estimated from the CPU seconds and the parallelism a quiet run of the demo reaches (``--parallelism``, measured:
docs/pipeline.md, "The demo's budget").

    python benchmarks/bench_demo_cpu.py --out DIR [--preset default] [--config FILE] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path
from typing import Any

from pgc.hookspecs import hookimpl


def cpu_seconds() -> float:
    """User + system CPU seconds of this process (all threads) and of its children that finished."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


class StageCPU:
    """Stage-event observer: wall and CPU seconds summed per stage name."""

    def __init__(self) -> None:
        self.open: dict[str, tuple[float, float]] = {}
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}

    @hookimpl
    def pgc_stage_started(self, stage: str, info: dict[str, Any]) -> None:
        self.open[stage] = (time.perf_counter(), cpu_seconds())

    @hookimpl
    def pgc_stage_finished(self, stage: str, seconds: float, figures: dict[str, Any]) -> None:
        start = self.open.pop(stage, None)
        if start is None:
            return
        self.wall[stage] = self.wall.get(stage, 0.0) + time.perf_counter() - start[0]
        self.cpu[stage] = self.cpu.get(stage, 0.0) + cpu_seconds() - start[1]


def main() -> None:
    from pgc.events import Reporter
    from pgc.pipeline.demo import run_demo
    from pgc.registry import Registry

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--preset", default="default")
    ap.add_argument("--config", default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--parallelism", type=float, default=1.51,
                    help="CPU seconds per wall second of a quiet demo run on the 2-core machine")
    ap.add_argument("--json", default=None, help="where to write the figures (default OUT/demo_cpu.json)")
    args = ap.parse_args()
    registry = Registry.discover()
    observer = StageCPU()
    registry.plugin_manager.register(observer, name="stage-cpu")
    cpu0, wall0 = cpu_seconds(), time.perf_counter()
    summary = run_demo(args.out, args.preset, args.config, seed=args.seed, reporter=Reporter(registry.hook),
                       registry=registry)
    total_cpu, total_wall = cpu_seconds() - cpu0, time.perf_counter() - wall0
    record = {"preset": args.preset, "seed": args.seed, "total_cpu_s": total_cpu, "total_wall_s": total_wall,
              "estimated_quiet_wall_s": total_cpu / args.parallelism, "parallelism": args.parallelism,
              "stages_cpu_s": observer.cpu, "stages_wall_s": observer.wall, "demo_steps_wall_s": summary["seconds"],
              "metrics": {k: summary[k] for k in ("hybrid", "3dgs_only", "pbr_only", "lights")}}
    Path(args.json or Path(args.out) / "demo_cpu.json").write_text(json.dumps(record, indent=2))
    print(f"total: {total_cpu:.0f} s CPU, {total_wall:.0f} s wall; quiet wall estimate "
          f"{total_cpu / args.parallelism:.0f} s")
    for stage in sorted(observer.cpu, key=observer.cpu.get, reverse=True):
        print(f"  {stage:<28} {observer.cpu[stage]:8.1f} s CPU {observer.wall[stage]:8.1f} s wall")


if __name__ == "__main__":
    main()
