#!/usr/bin/env python
"""Speed against error of the ``pbr_renderer`` implementations, screen space and texture space.

Scene: a folded cloth sheet (self-shadowing, inter-reflection) with a checker base colour and the paper's
BRDF (pgc-sheen), under a constant light and under an environment map, seen from one camera. Reference: the
``mitsuba`` path tracer at ``--ref-spp`` samples, measured in the same run. Each setting (mitsuba at several
spp, torch at several direction counts) is timed (median of ``--repeats`` warm runs) and compared with the
reference on covered pixels/texels: relative mean absolute error, PSNR (peak 1, linear radiance). Speed is
reported as the ratio of the reference's time to the setting's (x faster). peak_mb: the process's peak
resident memory after the run (monotonic; a coarse bound).

    python benchmarks/bench_pbr.py [--size 96] [--ref-spp 1024] [--out bench_pbr.json]

Material fit on synthetic captures (``pgc synth OUT --fabric F``): every model is fitted (ground-truth
garment mesh and base colour, the body as occluder) and compared on held-out views; the selection, the
recovered parameters against the ground truth and the fit times are recorded.

    python benchmarks/bench_pbr.py fit CAPTURE [CAPTURE ...] [--max-image-side 96] [--out bench_fit.json]

(fit settings: the material stage's defaults, ``pgc.pipeline.settings_material``, unless overridden)

Where the fitted models differ: each model of a ``fit`` JSON is rendered (``--spp``, default the fit's
``eval_spp``) on the capture's held-out and training views at the fit's image size, and its PSNR is split
between grazing interior garment pixels (|cos| between the pixel's view ray and the flat face it sees below
``--cos``) and the others. Two PSNRs: "plain", the selection's measure (one render: its Monte Carlo variance
adds to the error), and "decorrelated", from sum w (p_A - t)(p_B - t) over two independently seeded renders,
whose expectation is the squared error of the noise-free render (the renders' variance drops out; the
capture's own noise stays; it is itself noisy, and reads inf when its estimate is not positive: use a
high ``--spp``).

    python benchmarks/bench_pbr.py grazing CAPTURE FIT_JSON [--cos 0.3] [--spp N] [--out bench_grazing.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import time
from importlib.metadata import version
from pathlib import Path
from typing import Any, Callable

import numpy as np

from pgc.brdfs.fitdata import psnr_from_mse
from pgc.testing.pbr_scenes import checker_texture, folded_sheet, ring_cameras
from pgc.registry import default_registry
from pgc.types import Light, Material

MATERIAL = {"roughness": 0.8, "sheen_color": [0.6, 0.55, 0.35], "sheen_roughness": 0.35}


def envmap(size: int = 32) -> np.ndarray:
    h, w = size, 2 * size
    env = np.tile(np.array([0.15, 0.2, 0.35], np.float32), (h, w, 1))
    env[: h // 2, w // 4: w // 2] = [3.0, 2.6, 1.8]
    return env


def timed(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    out = fn()  # warm-up (JIT kernels, imports, visibility cache of the torch renderer)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def render_job(renderer: Any, space: str, mesh: Any, material: Material, light: Light, camera: Any,
               size: int) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
    """A call rendering in ``space`` ("screen" or "texture"): (radiance, mask of fully covered samples)."""
    def job() -> tuple[np.ndarray, np.ndarray]:
        if space == "screen":
            out = renderer.render(mesh, material, light, camera)
            return out.color, out.alpha > 0.999
        tex, cover = renderer.render_texture(mesh, material, light, camera, (size, size))
        return tex, cover > 0.99

    return job


def errors(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    d = pred[mask] - ref[mask]
    return {"rel_mae": float(np.abs(d).mean() / max(np.abs(ref[mask]).mean(), 1e-12)),
            "psnr": psnr_from_mse(float(np.mean(d ** 2)))}


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--size", type=int, default=96, help="image side (px) and texture side (texels)")
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 16, 64, 256])
    ap.add_argument("--directions", type=int, nargs="+", default=[64, 256, 1024])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default="bench_pbr.json")
    args = ap.parse_args(argv)

    reg = default_registry()
    mesh = folded_sheet(n=32)
    material = Material("pgc-sheen", MATERIAL, checker_texture(64))
    camera = ring_cameras(3, size=args.size, radius=1.8, arc_deg=100, elevation_deg=20)[1]
    lights = {"constant": Light(np.array([1.5, 1.4, 1.2])),
              "envmap": Light(np.ones(3), envmap=envmap(), rotation_deg=30.0)}
    settings: list[tuple[str, dict[str, Any]]] = [("mitsuba", {"spp": s}) for s in args.spp]
    settings += [("torch", {"directions": d, "threads": 1}) for d in args.directions]
    versions = {p: version(p) for p in ("mitsuba", "drjit", "torch", "open3d-cpu", "numpy")}
    records, rows = [], []
    for light_name, light in lights.items():
        for space in ("screen", "texture"):
            def run(name: str, opts: dict[str, Any]) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
                return render_job(reg.create("pbr_renderer", name, opts), space, mesh, material, light, camera,
                                  args.size)

            ref_seconds, (ref_img, ref_mask) = timed(run("mitsuba", {"spp": args.ref_spp}), 1)
            for name, opts in settings:
                seconds, (img, mask) = timed(run(name, opts), args.repeats)
                err = errors(img, ref_img, ref_mask & mask)
                peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
                preset = f"sheet-{light_name}-{space}-{args.size}"
                records.append({"role": "pbr_renderer", "implementation": name, "preset": preset,
                                "settings": opts, "seconds": seconds, "peak_mb": peak, "errors": err,
                                "speedup_vs_reference": ref_seconds / seconds, "reference": {
                                    "implementation": "mitsuba", "spp": args.ref_spp, "seconds": ref_seconds},
                                "versions": versions})
                rows.append([preset, name, ",".join(f"{k}={v}" for k, v in opts.items() if k != "threads"),
                             f"{ref_seconds / seconds:.1f}x", f"{err['rel_mae']:.4f}", f"{err['psnr']:.1f}"])
                print("  ".join(rows[-1]), flush=True)
    head = ["preset", "impl", "setting", "speed vs ref", "rel MAE", "PSNR dB"]
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    print("\n" + "  ".join(h.ljust(w) for h, w in zip(head, widths)))
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)))
    Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    print(f"wrote {len(records)} records to {args.out}")
    return records


def synthetic_fit_inputs(root: Path) -> tuple[Any, Any, Material, dict[str, Any]]:
    """(capture, garment + body mesh labelled 2/1, ground-truth base colour material, ground truth)."""
    from pgc.io.capture import read_capture
    from pgc.io.images import read_exr
    from pgc.io.mesh import read_mesh
    from pgc.types import Mesh

    capture = read_capture(root)
    gt = root / "ground_truth"
    truth = json.loads((gt / "material.json").read_text())
    truth["radiance"] = json.loads((gt / "light.json").read_text())["radiance"]
    garment, body = read_mesh(gt / "garment.obj"), read_mesh(gt / "body.obj")
    labels = {v: k for k, v in capture.labels.items()}
    uv = np.concatenate([garment.uv, np.zeros((1, 2), np.float32)])
    mesh = Mesh(np.concatenate([garment.vertices, body.vertices]),
                np.concatenate([garment.faces, body.faces + len(garment.vertices)]), uv,
                np.concatenate([garment.face_uv, np.full_like(body.faces, len(garment.uv))]),
                np.concatenate([np.full(len(garment.faces), capture.garment_label_ids[0]),
                                np.full(len(body.faces), labels.get("body", 1))]), name="garment+body")
    return capture, mesh, Material(truth["brdf"], {}, read_exr(gt / "base_color.exr")), truth


def fit_renderer(seed: int = 0) -> Any:
    """The ``mitsuba`` renderer of the fits (flat-shaded like the generator's meshes, no vertex normals)."""
    return default_registry().create("pbr_renderer", "mitsuba", {"max_depth": 4, "smooth_normals": False,
                                                                  "seed": seed})


def fit_main(argv: list[str]) -> list[dict[str, Any]]:
    from pgc.brdfs.select import fit_and_select
    from pgc.roles.pbr_renderer import MaterialFitSettings

    ap = argparse.ArgumentParser(description="material fit on synthetic captures")
    ap.add_argument("captures", nargs="+", type=Path)
    ap.add_argument("--max-iterations", type=int, help="default: the material stage's")
    ap.add_argument("--max-image-side", type=int, help="default: the material stage's")
    ap.add_argument("--out", default="bench_fit.json")
    args = ap.parse_args(argv)
    renderer = fit_renderer()
    settings = MaterialFitSettings(**{k: v for k, v in (("max_iterations", args.max_iterations),
                                                        ("max_image_side", args.max_image_side)) if v is not None})
    versions = {p: version(p) for p in ("mitsuba", "drjit", "numpy")}
    records = []
    for root in args.captures:
        capture, mesh, material, truth = synthetic_fit_inputs(root)
        fabric = capture.metadata.get("fabric", root.name)
        start = time.perf_counter()
        sel = fit_and_select(renderer, capture, mesh, material, settings)
        seconds = time.perf_counter() - start
        for model, row in sel.table.items():
            records.append({"role": "pbr_renderer", "implementation": "mitsuba", "preset": f"fit-{fabric}",
                            "settings": {"brdf": model, **settings.model_dump()}, "seconds": row["seconds"],
                            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                            "errors": {"psnr_holdout": row["psnr_holdout"]}, "iterations": row["iterations"],
                            "stopped": row["stopped"], "drift": row["drift"],
                            "params": row["params"], "radiance": row["radiance"], "truth": truth,
                            "chosen": sel.fit.material.brdf == model, "reason": sel.reason, "versions": versions})
            print(f"{fabric:12s} {model:10s} PSNR {row['psnr_holdout']:6.2f} dB  it {row['iterations']:4d}  "
                  f"{row['seconds']:6.1f} s  {row['params']}  L={np.round(row['radiance'], 3).tolist()}", flush=True)
        print(f"{fabric:12s} chosen: {sel.fit.material.brdf} ({sel.reason}); total {seconds:.0f} s; truth {truth}",
              flush=True)
        Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    fabrics = list(dict.fromkeys(r["preset"][4:] for r in records))
    print("\nheld-out PSNR dB (iterations, seconds); * = chosen\n" + "model".ljust(11)
          + "".join(f.ljust(24) for f in fabrics))
    for model in dict.fromkeys(r["settings"]["brdf"] for r in records):
        cells = {r["preset"][4:]: f"{r['errors']['psnr_holdout']:.2f}{'*' if r['chosen'] else ''} "
                 f"({r['iterations']} it, {r['seconds']:.0f} s)" for r in records if r["settings"]["brdf"] == model}
        print(model.ljust(11) + "".join(cells.get(f, "-").ljust(24) for f in fabrics))
    return records


def view_cosines(mesh: Any, camera: Any, occluder: Any) -> np.ndarray:
    """(H, W) |cos| between the ray through each pixel centre and the normal of the (flat) ``mesh`` face it
    sees first; NaN where it sees no face of ``mesh`` (background, or ``occluder`` in front)."""
    from pgc.texture.visibility import render_faces

    face = render_faces(mesh, camera, occluder=occluder).face_id
    _, rays = camera.rays()
    cos = np.abs(np.sum(mesh.face_normals()[np.maximum(face, 0)] * rays, axis=-1))
    return np.where(face >= 0, cos, np.nan)


def grazing_main(argv: list[str]) -> list[dict[str, Any]]:
    from pgc.brdfs.fitdata import masked_mse, prepare_views, split_occluders
    from pgc.brdfs.select import holdout_split
    from pgc.roles.pbr_renderer import MaterialFitSettings

    ap = argparse.ArgumentParser(description="held-out and training PSNR of fitted models: grazing pixels vs rest")
    ap.add_argument("capture", type=Path)
    ap.add_argument("fit_json", type=Path, help="the output of 'bench_pbr.py fit' that includes this capture")
    ap.add_argument("--cos", type=float, default=0.3, help="grazing: |cos(theta_o)| below this")
    ap.add_argument("--spp", type=int, help="samples per pixel of each render (default: the fit's eval_spp)")
    ap.add_argument("--out", default="bench_grazing.json")
    args = ap.parse_args(argv)
    capture, mesh, material, _ = synthetic_fit_inputs(args.capture)
    fabric = capture.metadata.get("fabric", args.capture.name)
    fits = [r for r in json.loads(args.fit_json.read_text()) if r["preset"] == f"fit-{fabric}"]
    if not fits:
        raise SystemExit(f"{args.fit_json} has no fit of fabric '{fabric}'")
    settings = MaterialFitSettings(**{k: v for k, v in fits[0]["settings"].items() if k != "brdf"})
    spp = args.spp or settings.eval_spp
    # seed 0 is the selection's render; 7919 an independent one (passes are seeded seed + pass index)
    renderers = [fit_renderer(seed) for seed in (0, 7919)]
    garment, occluder = split_occluders(mesh, tuple(capture.garment_label_ids))
    train, held = holdout_split(len(capture.views), settings.holdout_every)
    masks: dict[str, list[tuple[Any, dict[str, np.ndarray]]]] = {}
    for split, ids in (("held-out", held), ("training", train)):
        masks[split] = []
        for v in prepare_views(capture, settings.max_image_side, ids):
            cos = view_cosines(garment, v.camera, occluder)
            graze = (v.weight > 0) & (cos < args.cos)
            masks[split].append((v, {"grazing": graze.astype(np.float32),
                                     "rest": ((v.weight > 0) & ~graze).astype(np.float32), "all": v.weight}))
    records = []
    print(f"{fabric}: {settings.max_image_side} px, {spp} spp, grazing = interior pixels with |cos(theta_o)| "
          f"< {args.cos}; PSNR dB plain / decorrelated")
    print("model       views     pixels grazing/all   grazing        rest           all            "
          "mean residual grazing (RGB)")
    for fit in fits:
        model = fit["settings"]["brdf"]
        mat = Material(model, fit["params"], material.base_color)
        light = Light(np.asarray(fit["radiance"]))
        for split, views in masks.items():
            sq = {k: 0.0 for k in ("grazing", "rest", "all")}
            dec, n = dict.fromkeys(sq, 0.0), dict.fromkeys(sq, 0.0)
            resid = np.zeros(3)
            for v, ms in views:
                a, b = (r.render(garment, mat, light, v.camera, spp=spp, occluder=occluder,
                                 max_depth=settings.max_depth).color - v.target for r in renderers)
                for k, w in ms.items():
                    sq[k] += masked_mse(a, 0.0, w) * float(w.sum())
                    dec[k] += float(np.sum(w[..., None] * a * b)) / 3.0
                    n[k] += float(w.sum())
                resid += ((a + b) / 2 * ms["grazing"][..., None]).reshape(-1, 3).sum(axis=0)
            psnr = {k: psnr_from_mse(sq[k] / max(n[k], 1.0)) for k in sq}
            psnr_dec = {k: psnr_from_mse(dec[k] / max(n[k], 1.0)) for k in sq}
            resid /= max(n["grazing"], 1.0)
            records.append({"role": "pbr_renderer", "implementation": "mitsuba", "preset": f"grazing-{fabric}",
                            "settings": {"brdf": model, "views": split, "cos": args.cos, "render_spp": spp,
                                         **settings.model_dump()},
                            "errors": {**{f"psnr_{k}": v for k, v in psnr.items()},
                                       **{f"psnr_decorrelated_{k}": v for k, v in psnr_dec.items()}},
                            "pixels": n, "mean_residual_grazing": resid.tolist(), "params": fit["params"],
                            "radiance": fit["radiance"]})
            print(f"{model:11s} {split:9s} {int(n['grazing']):7d}/{int(n['all']):<7d}     "
                  + "".join(f"{psnr[k]:6.2f}/{psnr_dec[k]:6.2f}  " for k in sq) + f"{np.round(resid, 4).tolist()}",
                  flush=True)
    Path(args.out).write_text(json.dumps(records, indent=1) + "\n")
    return records


if __name__ == "__main__":
    import sys

    if len(sys.argv) > 1 and sys.argv[1] == "fit":
        fit_main(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "grazing":
        grazing_main(sys.argv[2:])
    else:
        main()
