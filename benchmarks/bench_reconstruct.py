#!/usr/bin/env python
"""Speed against accuracy of the reconstructors on one scene.

Each reconstructor runs in a fresh process (so its peak memory, ``ru_maxrss``, is its own) on the same
capture; its mesh is compared with the ground truth restricted to the faces that two or more cameras see
(the body under a garment cannot be reconstructed from images, and what one camera glimpses through a
sleeve or the hem cannot be triangulated; ``chamfer_mean_any_view`` uses every face some camera sees):
Chamfer mean / 95th percentile, normal consistency, F-score
at 5 mm and 1 cm, garment-label IoU, the remeshed surface's minimum angle and manifoldness, and seconds per
stage. Speed is also given as a ratio to the ``visual_hull`` baseline measured in the same run (the machine
is shared, wall-clock seconds are noisy). Records follow docs/bench.md, "Record schema".

    python benchmarks/bench_reconstruct.py [--capture DIR] [--implementations visual_hull open3d colmap mesh]
                                           [--target-vertices 15000] [--out bench_reconstruct.json]

Without ``--capture`` a default-like scene is made in-process (pgc.testing.capture_scenes: 32 views, 256 px).
With a ``pgc synth`` capture the ground truth is ``ground_truth/full.ply`` (face labels included).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import multiprocessing
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

from pgc.io.asset import package_versions

ROLE = "reconstructor"


def _reconstruct(name: str, capture: Any, options: dict[str, Any]) -> dict[str, Any]:
    """Child process: build and run one reconstructor; return its mesh arrays, figures, time and peak RSS."""
    from pgc.registry import Registry

    impl = Registry.discover().create(ROLE, name, options)
    start = time.perf_counter()
    rec = impl.reconstruct(capture)
    seconds = time.perf_counter() - start
    m = rec.mesh
    return {"vertices": m.vertices, "faces": m.faces, "uv": m.uv, "face_uv": m.face_uv, "labels": m.face_labels,
            "figures": rec.figures, "seconds": seconds,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def load_scene(capture_dir: str | None) -> tuple[Any, Any, str]:
    """The capture, its ground-truth mesh (with face labels) and a scene name."""
    if capture_dir is None:
        from pgc.testing.capture_scenes import body_mesh, make_capture

        cap, gt = make_capture(body_mesh(0.008), views=32, size=256)
        return cap, gt, "testscene-32x256"
    from pgc.io.capture import read_capture
    from pgc.io.mesh import read_mesh

    cap = read_capture(capture_dir)
    gt = read_mesh(Path(capture_dir) / "ground_truth" / "full.ply")
    return cap, gt, f"synth:{Path(capture_dir).name}"


def run(capture: str | None = None, implementations: tuple[str, ...] = ("visual_hull", "open3d", "colmap", "mesh"),
        target_vertices: int = 15_000, samples: int = 100_000, preset: str | None = None) -> list[dict[str, Any]]:
    """Benchmark records (one per implementation) on one scene; see the module docstring."""
    from pgc.geometry import metrics
    from pgc.io.mesh import write_mesh
    from pgc.types import Mesh

    cap, gt, scene = load_scene(capture)
    visible = metrics.visible_faces(gt, cap.cameras, min_views=2)
    glimpsed = metrics.visible_faces(gt, cap.cameras, min_views=1)
    gt_visible = gt.submesh(visible)[0]
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        scan = Path(tmp) / "scan.ply"
        write_mesh(scan, Mesh(gt.vertices, gt.faces))
        ctx = multiprocessing.get_context("spawn")
        for name in implementations:
            options: dict[str, Any] = {"target_vertices": target_vertices}
            if name == "mesh":
                options["path"] = str(scan)
            with cf.ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
                out = pool.submit(_reconstruct, name, cap, options).result()
            mesh = Mesh(out["vertices"], out["faces"], out["uv"], out["face_uv"], out["labels"])
            err = metrics.compare_meshes(mesh, gt, samples=samples, gt_faces=visible)
            errors = {k: err[k] for k in ("chamfer_mean", "chamfer_p95", "normal_consistency", "fscore_5mm",
                                          "fscore_10mm", "accuracy_mean", "completeness_mean")}
            errors["chamfer_mean_any_view"] = metrics.compare_meshes(mesh, gt, samples=samples,
                                                                     gt_faces=glimpsed)["chamfer_mean"]
            errors["garment_iou"] = metrics.label_iou(mesh, gt_visible, cap.garment_label_ids)
            errors["uv_overlap"] = metrics.uv_overlap(mesh, 1024)["overlap_fraction"]
            fig = out["figures"]
            print(f"{name}: {out['seconds']:.1f} s, chamfer {1000 * errors['chamfer_mean']:.2f} mm, "
                  f"garment IoU {errors['garment_iou']:.3f}", flush=True)
            records.append({
                "role": ROLE, "implementation": name, "preset": preset or scene,
                "settings": options | {"views": len(cap.views), "image": f"{cap.views[0].camera.width}x{cap.views[0].camera.height}"},
                "seconds": out["seconds"], "peak_mb": out["peak_mb"], "errors": errors,
                "stages": {k: v for k, v in fig.items() if k.startswith("seconds_")},
                "mesh": {k: fig[k] for k in ("vertices", "faces", "min_angle_deg", "non_manifold_edges",
                                             "non_manifold_vertices", "boundary_edges", "components") if k in fig},
                "versions": package_versions(("pgc", "numpy", "scipy", "open3d-cpu", "pycolmap", "pymeshlab", "xatlas",
                                              "opencv-python-headless")),
            })
    base = next((r["seconds"] for r in records if r["implementation"] == "visual_hull"), None)
    for r in records:
        r["speed_ratio_vs_visual_hull"] = None if base is None else r["seconds"] / base
    return records


def print_table(records: list[dict[str, Any]]) -> None:
    head = f"{'implementation':<12} {'s':>7} {'x hull':>6} {'MB':>6} {'CD mean mm':>10} {'CD p95 mm':>9} " \
           f"{'NC':>6} {'F@5mm':>6} {'F@1cm':>6} {'IoU':>6} {'min ang':>7}"
    print(head)
    print("-" * len(head))
    for r in records:
        e = r["errors"]
        ratio = r["speed_ratio_vs_visual_hull"]
        print(f"{r['implementation']:<12} {r['seconds']:7.1f} {ratio if ratio is not None else float('nan'):6.2f} "
              f"{r['peak_mb']:6.0f} {1000 * e['chamfer_mean']:10.2f} {1000 * e['chamfer_p95']:9.2f} "
              f"{e['normal_consistency']:6.3f} {e['fscore_5mm']:6.3f} {e['fscore_10mm']:6.3f} "
              f"{e['garment_iou']:6.3f} {r['mesh'].get('min_angle_deg', float('nan')):7.1f}")


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--capture", default=None, help="a capture directory with ground_truth/full.ply (pgc synth)")
    ap.add_argument("--implementations", nargs="+", default=["visual_hull", "open3d", "colmap", "mesh"])
    ap.add_argument("--target-vertices", type=int, default=15_000)
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--out", default="bench_reconstruct.json")
    args = ap.parse_args(argv)
    records = run(args.capture, tuple(args.implementations), args.target_vertices, args.samples)
    print_table(records)
    Path(args.out).write_text(json.dumps(records, indent=1, default=float))
    print(f"wrote {args.out}")
    return records


if __name__ == "__main__":
    main()
