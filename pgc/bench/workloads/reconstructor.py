"""reconstructor: the synthetic capture (``pgc synth``) to a mesh, against its ground-truth mesh.

The ground truth is ``ground_truth/full.ply`` restricted to the faces some camera sees (the body under the
garment cannot be reconstructed from images). Reference (speed base): ``visual_hull``. Errors (metres):
``chamfer_mean`` (plotted), ``chamfer_p95``, ``accuracy_mean``, ``completeness_mean``, and
``one_minus_fscore_10mm``, ``one_minus_normal_consistency``, ``one_minus_garment_iou`` (so that lower is
better everywhere); the mesh statistics and per-stage seconds go to the detail file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pgc.bench.measure import timed
from pgc.bench.workloads import Context

ERROR_KEY = "chamfer_mean"
REFERENCE = "visual_hull"


def bench(ctx: Context) -> list[dict[str, Any]]:
    from pgc.geometry import metrics
    from pgc.io.capture import read_capture
    from pgc.io.mesh import read_mesh

    root = Path(ctx.capture_dir())
    capture = read_capture(root)
    gt = read_mesh(root / "ground_truth" / "full.ply")
    visible = metrics.visible_faces(gt, capture.cameras)
    gt_visible = gt.submesh(visible)[0]
    samples = int(ctx.param("samples", 20_000))
    cam = capture.views[0].camera
    case = f"{len(capture.views)} views {cam.width}x{cam.height}"
    records = []
    for run in ctx.runs:
        settings = {"views": len(capture.views), "options": run.options}
        try:
            impl = ctx.create(run)
            t = timed(lambda: impl.reconstruct(capture), 1, warmup=False)
            mesh = t.value.mesh
            err = metrics.compare_meshes(mesh, gt, samples=samples, gt_faces=visible)
            iou = metrics.label_iou(mesh, gt_visible, capture.garment_label_ids)
        except Exception as exc:  # a failing reconstructor is reported, the others still run
            records.append(ctx.failed(run.implementation, case, settings, exc, ERROR_KEY))
            continue
        errors = {k: err[k] for k in ("chamfer_mean", "chamfer_p95", "accuracy_mean", "completeness_mean")}
        errors |= {"one_minus_fscore_10mm": 1.0 - err["fscore_10mm"],
                   "one_minus_normal_consistency": 1.0 - err["normal_consistency"], "one_minus_garment_iou": 1.0 - iou}
        figures = {k: v for k, v in t.value.figures.items() if isinstance(v, (int, float, str, bool))}
        records.append(ctx.record(run.implementation, case, settings, t.seconds, t.peak_mb, errors, ERROR_KEY,
                                  reference=run.implementation == REFERENCE and not run.options,
                                  detail={"figures": figures, "metrics": err, "garment_iou": iou}))
    return records
