"""The demo's HTML report: image strips, the frequency decomposition, metric tables, stage timings."""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np

from pgc.io.atomic import write_text
from pgc.io.images import write_image
from pgc.pipeline.evaluate import VARIANTS

STRIP = ("ground truth", "3DGS-only", "PBR-only", "hybrid", "|hybrid - gt| x4")
DECOMPOSITION = ("l(S) low-pass of the far field", "h(G) high-pass of the near field (0.5 + h)")
SLUGS = dict(zip(STRIP + DECOMPOSITION, ("gt", "3dgs_only", "pbr_only", "hybrid", "error", "low_far", "high_near")))


def _strip_images(run: Path, frame: int, camera: int) -> dict[str, np.ndarray]:
    pred = np.load(run / "render" / f"frame_{frame:04d}.npz")
    gt_file = next((run / "gt").glob(f"frame_{frame:04d}_spp*.npz"), None)
    out = {"3DGS-only": pred["near"][camera], "PBR-only": pred["pbr"][camera], "hybrid": pred["hybrid"][camera],
           DECOMPOSITION[0]: pred["low_far"][camera], DECOMPOSITION[1]: 0.5 + pred["high_near"][camera]}
    if gt_file is not None:
        gt = np.load(gt_file)
        target = gt["color"][camera] * gt["garment_mask"][camera][..., None]
        out["ground truth"] = target
        out["|hybrid - gt| x4"] = np.abs(pred["hybrid"][camera] - target) * 4
    return out


def write_report(out: str | Path, summary: dict[str, Any], results: dict[str, dict[str, Any]]) -> Path:
    """Write ``OUT/report.html`` (+ PNGs in ``OUT/report/``) from the demo's results."""
    out = Path(out)
    figs = out / "report"
    rows = []
    for motion, res in results.items():
        run = Path(res["run"])
        frames = res["frames"]
        frame = frames[len(frames) // 2]
        images = _strip_images(run, frame, 0)
        cells = []
        for label in STRIP + DECOMPOSITION:
            if label not in images:
                continue
            name = f"{motion}_{frame:04d}_{SLUGS[label]}.png"
            write_image(figs / name, np.clip(images[label], 0, 1))
            cells.append(f"<figure><img src='report/{html.escape(name)}'><figcaption>{html.escape(label)}"
                         "</figcaption></figure>")
        rows.append(f"<h3>{html.escape(motion)} (frame {frame})</h3><div class='strip'>{''.join(cells)}</div>")
    metric_names = [k for k in summary["hybrid"]]
    head = "".join(f"<th>{html.escape(m)}</th>" for m in metric_names)
    body = "".join(f"<tr><td>{v}</td>" + "".join(f"<td>{summary[v][m]:.4f}</td>" for m in metric_names) + "</tr>"
                   for v in VARIANTS)
    per_motion = "".join(
        f"<tr><td>{html.escape(mo)}</td><td>{v}</td>" + "".join(f"<td>{r[v][m]:.4f}</td>" for m in metric_names)
        + "</tr>" for mo, r in summary["motions"].items() for v in VARIANTS)
    timing = "".join(f"<tr><td>{html.escape(k)}</td><td>{v:.1f}</td></tr>"
                     for k, v in {**summary.get("stages", {}), **summary.get("seconds", {})}.items())
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>PGC demo report</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse}} td,th{{border:1px solid #ccc;
padding:4px 8px;text-align:right}} .strip{{display:flex;gap:6px;flex-wrap:wrap}} figure{{margin:0}}
img{{width:192px;image-rendering:pixelated}} figcaption{{font-size:12px;text-align:center}}</style></head><body>
<h1>PGC demo: preset '{html.escape(str(summary.get("preset")))}'</h1>
<p>Novel-pose frames of the paper's test motions, rendered by the hybrid renderer and its ablations, against
ground truth rendered with the true materials on the same simulated geometry. Metrics are restricted to the
garment region (mean over frames, cameras and motions). FSIM, SSIM, PSNR: higher is better; LPIPS: lower.</p>
<h2>Metrics</h2><table><tr><th>variant</th>{head}</tr>{body}</table>
<h2>Per motion</h2><table><tr><th>motion</th><th>variant</th>{head}</tr>{per_motion}</table>
<h2>Images</h2>{''.join(rows)}
<h2>Timings (seconds)</h2><table>{timing}</table>
<h2>Resolved configuration</h2><pre>{html.escape(json.dumps(summary.get("config", {}), indent=1))}</pre>
</body></html>"""
    path = out / "report.html"
    write_text(path, page)
    return path
