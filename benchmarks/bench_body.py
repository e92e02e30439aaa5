#!/usr/bin/env python
"""Speed, memory and accuracy of the ``anny`` body model per mesh topology.

    python benchmarks/bench_body.py [--topologies notoes_collapse10pc notoes] [--fresh] [--out bench_body.json]

Per topology: building the model in a new process from Anny's disk cache (import and build timed apart), the
rest forward pass, a posed forward pass, skinning a 120-frame clip (the role's numpy ``skin``, float64 inside)
and one float32 batch of 120 frames with its backward pass through the shape (``forward_torch``, what a body
fit runs). Error: distance (m) from the vertices of the full ``notoes`` mesh to the topology's surface, for the
default shape in the rest pose (mean, 95th percentile, max). ``--fresh`` also times the first build into an
empty cache folder (minutes) and reports the size of the cache it writes. Records (JSON) follow
docs/bench.md, "Record schema".
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

CLIP_FRAMES = 120

BUILD_SNIPPET = """
import json, sys, time
t = time.perf_counter()
from pgc.body.anny import build_anny, import_anny
import_anny()
t1 = time.perf_counter()
build_anny(sys.argv[1])
t2 = time.perf_counter()
from pgc.bench.measure import _rss_mb
print(json.dumps({"import_s": t1 - t, "build_s": t2 - t1, "rss_mb": _rss_mb()}))
"""


def build_in_new_process(topology: str, cache_dir: str | None = None) -> dict[str, Any]:
    """Import and build times (s) and resident memory (MB) of a new process that builds ``topology``."""
    env = dict(os.environ, **({"ANNY_CACHE_DIR": cache_dir} if cache_dir else {}))
    out = subprocess.run([sys.executable, "-c", BUILD_SNIPPET, topology], env=env, check=True, capture_output=True,
                         text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def folder_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) / 1e6


def clip_rotations(body, frames: int) -> np.ndarray:
    """A swinging-arms-and-legs clip: local rotations (T, J, 3, 3) about X of up to 0.8 rad."""
    from pgc.motion.rotations import axis_angle_to_matrix

    names = body.joint_names
    rotations = np.broadcast_to(np.eye(3), (frames, len(names), 3, 3)).copy()
    swing = 0.8 * np.sin(np.linspace(0, 2 * np.pi, frames))
    for t, a in enumerate(swing):
        for name, sign in (("LeftArm", 1), ("RightArm", -1), ("LeftUpLeg", -0.5), ("RightUpLeg", 0.5),
                           ("LeftForeArm", 0.5), ("RightForeArm", 0.5)):
            if name in names:
                rotations[t, names.index(name)] = axis_angle_to_matrix(np.array([sign * a, 0.0, 0.0]))
    return rotations


def bench_topology(topology: str, fine_mesh, repeats: int) -> dict[str, Any]:
    import torch

    from pgc.bench.measure import timed
    from pgc.body.anny import AnnyBody
    from pgc.geometry.metrics import point_mesh_distance

    body = AnnyBody({"topology": topology})
    rotations = clip_rotations(body, CLIP_FRAMES)
    rest = timed(lambda: body.forward(), repeats)
    posed = timed(lambda: body.forward(None, rotations[CLIP_FRAMES // 4]), repeats)
    clip = timed(lambda: body.skin(None, rotations), repeats)
    shape = body.check_shape(None)

    def fit_step() -> None:
        params = {k: torch.tensor([v], dtype=torch.float32, requires_grad=True) for k, v in shape.items()}
        out = body.forward_torch(params, torch.tensor(rotations, dtype=torch.float32),
                                 torch.zeros(CLIP_FRAMES, 3, dtype=torch.float32))
        out.vertices.square().mean().backward()

    grad = timed(fit_step, repeats)
    distance, _ = point_mesh_distance(fine_mesh.vertices, body.mesh(), candidates=32)
    return {"vertices": len(body.mesh().vertices), "faces": len(body.faces), "rest_s": rest.seconds,
            "posed_s": posed.seconds, "skin_clip_s": clip.seconds, "skin_clip_peak_mb": clip.peak_mb,
            "fit_step_s": grad.seconds, "fit_step_peak_mb": grad.peak_mb,
            "errors": {"to_full_mean_m": float(distance.mean()), "to_full_p95_m": float(np.percentile(distance, 95)),
                       "to_full_max_m": float(distance.max())}}


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    from pgc.builtin_plugins.specs_body import ANNY_TOPOLOGIES

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--topologies", nargs="+", choices=ANNY_TOPOLOGIES, default=list(ANNY_TOPOLOGIES))
    p.add_argument("--fresh", action="store_true", help="also time the first build into an empty cache (minutes)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", type=Path, default=Path("bench_body.json"))
    args = p.parse_args(argv)
    from pgc.bench.measure import versions
    from pgc.body.anny import AnnyBody

    env = versions()
    fine = AnnyBody({"topology": "notoes"}).mesh()
    records, rows = [], []
    for topology in args.topologies:
        cached = build_in_new_process(topology)
        result = bench_topology(topology, fine, args.repeats)
        settings: dict[str, Any] = {"topology": topology, "vertices": result.pop("vertices"),
                                    "faces": result.pop("faces"), "clip_frames": CLIP_FRAMES,
                                    "import_s": cached["import_s"], "cached_build_s": cached["build_s"],
                                    "process_rss_mb": cached["rss_mb"]}
        if args.fresh:
            with tempfile.TemporaryDirectory(prefix="anny-cache-") as cache:
                start = time.perf_counter()
                first = build_in_new_process(topology, cache)
                settings.update(first_build_s=first["build_s"], first_build_wall_s=time.perf_counter() - start,
                                first_build_cache_mb=folder_mb(Path(cache)))
        errors = result.pop("errors")
        records.append({"role": "body_model", "implementation": "anny", "preset": topology,
                        "settings": {**settings, **{k: v for k, v in result.items() if k != "skin_clip_s"}},
                        "seconds": result["skin_clip_s"], "peak_mb": result["skin_clip_peak_mb"], "errors": errors,
                        "error_key": "to_full_p95_m", "versions": env})
        rows.append({"topology": topology, "V": settings["vertices"],
                     "import s": f"{cached['import_s']:.1f}", "build s": f"{cached['build_s']:.2f}",
                     "first build s": f"{settings['first_build_s']:.0f}" if args.fresh else "-",
                     "rest ms": f"{1e3 * result['rest_s']:.0f}", "posed ms": f"{1e3 * result['posed_s']:.0f}",
                     f"skin {CLIP_FRAMES} s": f"{result['skin_clip_s']:.2f}",
                     "fit step s": f"{result['fit_step_s']:.2f}", "peak MB": f"{result['fit_step_peak_mb']:.0f}",
                     "err mean/p95/max mm": "/".join(f"{1e3 * errors[k]:.1f}" for k in
                                                     ("to_full_mean_m", "to_full_p95_m", "to_full_max_m"))})
        print(" ".join(f"{k}={v}" for k, v in rows[-1].items()), flush=True)
    columns = list(rows[0])
    widths = [max(len(c), *(len(str(r[c])) for r in rows)) for c in columns]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    for r in rows:
        print("  ".join(str(r[c]).ljust(w) for c, w in zip(columns, widths)))
    args.out.write_text(json.dumps(records, indent=1) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
