"""Synthetic capture: render noise against samples per pixel (per sampler) and generation time per preset.

Noise: two renders of the same view with different seeds; the per-pixel noise standard deviation is
RMS(a - b) / sqrt(2) over the covered pixels. Bias: the mean over the covered pixels against a
high-sample reference render. Speed is reported as a ratio to the reference render measured in the same
run (the machine is shared, wall-clock seconds are noisy).

    python benchmarks/bench_synth.py [--out DIR] [--presets tiny,default] [--resolution 128]

Prints a table and writes ``bench_synth.json`` (one record per run: role, implementation, preset,
settings, seconds, peak_mb, errors, versions).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

from pgc.io.asset import package_versions


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def noise_study(resolution: int, fabric: str, spps: list[int], samplers: list[str], ref_spp: int) -> list[dict]:
    from pgc.synth import fabrics, garments, rig
    from pgc.synth.body import make_body
    from pgc.config import load
    from pgc.roles.scene_renderer import SceneGeometry
    from pgc.synth.render import scene_renderer

    cfg = load()
    renderer = scene_renderer(cfg)
    body = make_body(cfg.create("body_model"))
    cloth = garments.make_garment(body, "tshirt", resolution=0.03)
    fab = fabrics.get_fabric(fabric)
    material, normal_map = fabrics.make_material(fab, cloth, 512, 0)
    fibres = fabrics.make_fibres(fab, cloth, material, 0)
    geometry = SceneGeometry(body.vertices, body.faces, cloth, material, normal_map, fibres)
    scene, labels = renderer.build_scene(geometry, rig.capture_light())
    cam = rig.dome_cameras(8, resolution, resolution, center=(0, 0.85, 0), distance=2.6, subject_radius=0.88)[2]
    fg = renderer.ground_truth_layers(scene, labels, geometry, cam, 2)["mask"] == 1

    def render(spp: int, seed: int, sampler: str) -> tuple[np.ndarray, float]:
        renderer.render_color(scene, cam, spp, seed, sampler)  # compile first (kernels are cached)
        t = time.perf_counter()
        img, _ = renderer.render_color(scene, cam, spp, seed, sampler)
        return img, time.perf_counter() - t

    reference, ref_seconds = render(ref_spp, 999, "independent")
    records = []
    for sampler in samplers:
        for spp in spps:
            a, seconds = render(spp, 1, sampler)
            b, _ = render(spp, 2, sampler)
            noise = float(np.sqrt(np.mean((a[fg] - b[fg]) ** 2) / 2))
            bias = float(np.abs(a[fg].mean(axis=0) - reference[fg].mean(axis=0)).max())
            records.append({"role": "synth_render", "implementation": f"mitsuba-path/{sampler}", "preset": fabric,
                            "settings": {"spp": spp, "resolution": resolution, "reference_spp": ref_spp},
                            "seconds": seconds, "seconds_ratio_to_reference": seconds / ref_seconds,
                            "peak_mb": _peak_mb(),
                            "errors": {"noise_std": noise, "noise_psnr_db": float(-20 * np.log10(max(noise, 1e-12))),
                                       "bias_mean": bias},
                            "versions": package_versions(("pgc", "numpy", "mitsuba", "drjit", "scikit-image"))})
    return records


def preset_times(presets: list[str], out: Path) -> list[dict]:
    from pgc.config import load
    from pgc.events import Reporter
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.render import scene_renderer

    cfg = load()
    renderer, body_model = scene_renderer(cfg), cfg.create("body_model")
    records = []
    for name in presets:
        reporter = Reporter.silent()
        t = time.perf_counter()
        generate(out / f"capture_{name}", name, reporter=reporter, renderer=renderer, body_model=body_model)
        seconds = time.perf_counter() - t
        p = get_preset(name)
        records.append({"role": "synth", "implementation": "pgc-synth", "preset": name,
                        "settings": {"views": p.views, "resolution": p.resolution, "spp": p.spp},
                        "seconds": seconds, "stage_seconds": reporter.timings, "peak_mb": _peak_mb(), "errors": {},
                        "versions": package_versions(("pgc", "numpy", "mitsuba", "drjit", "scikit-image"))})
    return records


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="runs/bench_synth")
    ap.add_argument("--presets", default="tiny,default")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--fabric", default="fleece")
    ap.add_argument("--spps", default="16,64,256", help="powers of 4 (the ldsampler needs them)")
    ap.add_argument("--samplers", default="independent,multijitter,ldsampler", help="'' skips the noise study")
    ap.add_argument("--reference-spp", type=int, default=2048)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    records = noise_study(args.resolution, args.fabric, [int(s) for s in args.spps.split(",")],
                          args.samplers.split(","), args.reference_spp) if args.samplers else []
    print(f"{'sampler':28s} {'spp':>5s} {'time/ref':>9s} {'noise std':>10s} {'noise dB':>9s} {'bias':>8s}")
    for r in records:
        e = r["errors"]
        print(f"{r['implementation']:28s} {r['settings']['spp']:5d} {r['seconds_ratio_to_reference']:9.3f} "
              f"{e['noise_std']:10.4f} {e['noise_psnr_db']:9.1f} {e['bias_mean']:8.4f}")
    if args.presets:
        timed = preset_times(args.presets.split(","), out)
        print(f"\n{'preset':10s} {'views':>5s} {'px':>5s} {'spp':>5s} {'seconds':>8s}  stages")
        for r in timed:
            s = r["settings"]
            stages = ", ".join(f"{k}={v:.1f}" for k, v in r["stage_seconds"].items())
            print(f"{r['preset']:10s} {s['views']:5d} {s['resolution']:5d} {s['spp']:5d} {r['seconds']:8.1f}  {stages}")
        records += timed
    (out / "bench_synth.json").write_text(json.dumps(records, indent=2))
    print(f"\nwrote {out / 'bench_synth.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
