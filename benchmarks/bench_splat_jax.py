#!/usr/bin/env python
"""Speed against error of the JAX splat renderer: its fused compositor and the block sizes (tile, chunk) of its
XLA compositor, against the torch renderer (its default, fused path).

For each scene (Gaussians on the surface of the test body seen by a dome camera, as in bench_splat.py, and a
tiny random scene where the float64 per-pixel reference runs), every JAX setting ('fused', or
TILExCHUNK for the XLA compositor) is timed forward (``render``) and forward+backward (one jitted gradient of
the image w.r.t. every world parameter; the XLA compositor's host binning included; compilation excluded,
it is reported separately), as ratios to the torch renderer measured in the same run. Errors: largest
absolute colour difference to the reference (tiny scene) or to the torch image; relative difference of the
gradients to torch's. Records (JSON) follow docs/bench.md, "Record schema".

    python benchmarks/bench_splat_jax.py [--sizes 128 256] [--counts 10000 50000] [--blocks fused 8x16 16x32]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_filter import print_table, timed  # noqa: E402
from bench_splat import jax_backward, surface_scene, tiny_scene, torch_backward  # noqa: E402


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--counts", type=int, nargs="+", default=[10000, 50000])
    parser.add_argument("--blocks", nargs="+", default=["fused", "8x16", "16x32"],
                        help="JAX settings to compare: 'fused', or TILExCHUNK of the XLA compositor")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-torch", action="store_true", help="skip torch (ratios then are to the first JAX row)")
    parser.add_argument("--out", default="bench_splat_jax.json")
    args = parser.parse_args(argv)

    from pgc.io.asset import package_versions
    from pgc.splats.reference import render_reference
    from pgc_jax.splat.renderer import JaxSplatRenderer

    env = package_versions(("pgc", "numpy", "torch", "jax", "jaxlib"))
    scenes = [("tiny", *tiny_scene())] + [(f"{s}px/{n // 1000}k", *surface_scene(n, s))
                                           for s in args.sizes for n in args.counts]
    records, rows = [], []
    for label, world, camera in scenes:
        ref = None
        if label == "tiny":
            start = time.perf_counter()
            ref = render_reference(world, camera).color
            ref_s = time.perf_counter() - start
        runs: list[tuple[str, dict, Any, Any]] = []
        if not args.no_torch:
            from pgc_torch.splat.renderer import TorchSplatRenderer
            torch_r = TorchSplatRenderer()
            runs.append(("torch", {}, lambda r=torch_r: r.render(world, camera), torch_backward(torch_r, world, camera)))
        for block in args.blocks:
            if block == "fused":
                opts = {"compositor": "fused"}
            else:
                tile, chunk = (int(x) for x in block.split("x"))
                opts = {"compositor": "xla", "tile_size": tile, "chunk_size": chunk}
            jr = JaxSplatRenderer(opts)
            runs.append(("jax", opts, lambda r=jr: r.render(world, camera), jax_backward(jr, world, camera)))
        base_img = base_grads = base_f = base_b = None
        for name, opts, fwd_fn, bwd_fn in runs:
            start = time.perf_counter()
            image = fwd_fn().color
            grads = bwd_fn()
            first_call = time.perf_counter() - start          # includes compilation for JAX
            fwd, peak = timed(fwd_fn, args.repeats)
            bwd, peak_b = timed(bwd_fn, args.repeats)
            if base_img is None:
                base_img, base_grads, base_f, base_b = image, grads, fwd, bwd
            grad_rel = max(float(np.linalg.norm(g - h) / max(np.linalg.norm(h), 1e-30))
                           for g, h in zip(grads, base_grads))
            errors = {"fwd_ratio_to_first": fwd / base_f, "fwdbwd_ratio_to_first": bwd / base_b,
                      "max_abs_vs_first": float(np.abs(image - base_img).max()), "grad_rel_vs_first": grad_rel,
                      "first_call_seconds": first_call}
            if ref is not None:
                errors |= {"max_abs_vs_reference": float(np.abs(image - ref).max()), "reference_seconds": ref_s,
                           "speedup_vs_reference": ref_s / fwd}
            records.append({"role": "splat_renderer", "implementation": name, "preset": label,
                            "settings": dict(opts, size=camera.width, gaussians=len(world.means)), "seconds": fwd,
                            "seconds_forward_backward": bwd, "peak_mb": round(max(peak, peak_b), 1),
                            "errors": errors, "versions": env})
            shown = name + (" fused" if opts.get("compositor") == "fused" else
                            f" {opts['tile_size']}x{opts['chunk_size']}" if opts else "")
            rows.append({"scene": label, "backend": shown,
                         "fwd ms": f"{1e3 * fwd:.0f}", "fwd+bwd ms": f"{1e3 * bwd:.0f}",
                         "fwd / first": f"{fwd / base_f:.2f}", "fwd+bwd / first": f"{bwd / base_b:.2f}",
                         "1st call s": f"{first_call:.1f}",
                         "max err": f"{errors.get('max_abs_vs_reference', errors['max_abs_vs_first']):.1e}",
                         "grad rel": f"{grad_rel:.1e}", "peak MB": f"{max(peak, peak_b):.0f}"})
            print(rows[-1], flush=True)
    print_table(rows, ["scene", "backend", "fwd ms", "fwd+bwd ms", "fwd / first", "fwd+bwd / first", "1st call s",
                       "max err", "grad rel", "peak MB"])
    Path(args.out).write_text(json.dumps(records, indent=1, default=float) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


if __name__ == "__main__":
    main()
