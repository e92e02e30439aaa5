"""The HTML report of a demo folder or a run: what the garment looks like in motion and under new light.

Per motion (camera 0 of the rendered cameras, cropped to the garment and enlarged by nearest neighbour):
a strip ground truth | 3DGS-only | PBR-only | hybrid with an error heatmap per variant, the hybrid's
decomposition ``l(S)`` (low-pass far field) and ``h(G)`` (high-pass near field), a looping animated WebP of
ground truth and hybrid side by side over the rendered frames, and, when the run was rendered with
``--rotate-light``, its relighting strip. Charts (SVG): metrics per motion, stage timings, and speed
against error from ``pgc bench`` records when given; under each novel light (a run's relit runs,
:mod:`pgc.pipeline.relight`), each motion's frames next to ground truth under that light with error heatmaps, and
a variant x light table; the first run's garment on its body in an interactive 3D
viewer (:mod:`pgc.pipeline.report_3d`). Everything lives in ``OUT/report.html`` and
``OUT/report/`` (relative links, no network); the page states its own size.
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.atomic import write_text
from pgc.io.limits import read_json
from pgc.pipeline import report_figures as figs
from pgc.pipeline.evaluate import VARIANTS
from pgc.pipeline.report_3d import view_section

FIGURES = "report"
"""Folder of the report's pictures, beside report.html."""
STRIP = (("gt", "ground truth"), ("3dgs_only", "3DGS-only"), ("pbr_only", "PBR-only"), ("hybrid", "hybrid"))
RELIGHT_FRAMES = 8
"""Frames of a rotating-light run shown in its strip (spread over the rendered frames)."""
PSNR_NAMES = ("psnr", "psnr-exposure")
"""The PSNR metrics whose change from the capture light the lights table shows (dB)."""


@dataclass
class RunView:
    """What the report reads of one run folder."""

    motion: str
    folder: Path
    render: dict[str, Any]
    run: dict[str, Any]
    metrics: dict[str, Any] | None = None
    frames: list[int] = field(default_factory=list)


def read_run_view(folder: Path, motion: str | None = None) -> RunView:
    """A run folder's render metadata, run.json and (if evaluated) metrics.json."""
    from pgc.pipeline.animate import read_run
    from pgc.pipeline.evaluate import rendered_frames

    run = read_run(folder)
    render, frames = rendered_frames(folder)
    metrics_path = folder / "metrics.json"
    metrics = read_json(metrics_path, "metrics.json") if metrics_path.is_file() else None
    return RunView(motion or str(run.get("motion", folder.name)), folder, render, run, metrics, frames)


def ground_truth_frame(folder: Path, frame: int, light: dict[str, Any]) -> np.ndarray | None:
    """(C, H, W, 3) ground-truth garment over black for ``frame`` rendered under ``light`` (a light record; the
    newest such cached ground truth: its ``light.json`` names the same light, and a cache without one was
    rendered under the capture light), or None."""
    from pgc.io.light_record import GT_LIGHT_FILE, capture_record, same_light

    found = []
    for path in (folder / "gt").glob(f"*/frame_{frame:04d}_spp*.npz"):
        record_path = path.parent / GT_LIGHT_FILE
        try:
            record = read_json(record_path, GT_LIGHT_FILE) if record_path.is_file() else capture_record()
        except PGCDataError:
            continue
        if isinstance(record, dict) and same_light(record, light, [frame]):
            found.append(path)
    if not found:
        return None
    with np.load(max(found, key=lambda p: p.stat().st_mtime)) as gt:
        return gt["color"] * gt["garment_mask"][..., None]


def render_light_record(view: RunView) -> dict[str, Any] | None:
    """The light record of the run's frames (:func:`pgc.io.light_record.render_light`), or None when it cannot
    be checked (an environment map that was not recorded, moved or changed)."""
    from pgc.pipeline.evaluate import run_light

    try:
        return run_light(view.folder, view.render, view.frames)
    except PGCDataError:
        return None


class _Figures:
    """Writes pictures into the figures folder and remembers them (for the size and the stale-file sweep)."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.folder = out / FIGURES
        self.written: list[Path] = []

    def path(self, name: str) -> Path:
        p = self.folder / name
        self.written.append(p)
        return p

    def img(self, name: str, caption: str, cls: str = "") -> str:
        c = f" class='{cls}'" if cls else ""
        return (f"<figure><img{c} src='{FIGURES}/{html.escape(name)}' alt='{html.escape(caption)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>")

    def sweep(self) -> None:
        """Remove pictures of an earlier report that this one did not write."""
        keep = {p.name for p in self.written}
        for p in self.folder.glob("*"):
            if p.is_file() and p.name not in keep:
                p.unlink()


def _motion_section(view: RunView, f: _Figures) -> str:
    frames = view.frames
    cam = 0
    slug = view.motion.replace("/", "_")
    strip = _truth_strip(view, f, slug)
    preds, gts, box, k, t, layers = strip.preds, strip.gts, strip.box, strip.k, strip.frame, strip.layers
    has_gt = all(g is not None for g in gts)
    pred = preds[len(frames) // 2]
    cells, heat = strip.cells, strip.heat
    detail = _detail_section(layers, pred, cam, f, f"{slug}_{t:04d}")
    dec = []
    for key, label, value in (("low_far", "l(S): low-pass of the far field", pred["low_far"][cam]),
                              ("high_near", "h(G): high-pass of the near field, shown as 0.5 + h",
                               0.5 + pred["high_near"][cam])):
        name = f"{slug}_{t:04d}_{key}.png"
        figs.save_png(f.path(name), figs.to_rgb8(figs.crop(np.clip(value, 0, 1), box, k)))
        dec.append(f.img(name, label, "crop"))
    fps = float(view.run.get("fps", 30.0))
    stride = frames[1] - frames[0] if len(frames) > 1 else 1
    frame_ms = max(100, int(round(1000 * stride / fps)))
    loop = []
    for i, p in enumerate(preds):
        parts = [figs.to_rgb8(figs.crop(p["hybrid"][cam], box, k))]
        if has_gt:
            parts.insert(0, figs.to_rgb8(figs.crop(gts[i][cam], box, k)))
        loop.append(figs.side_by_side(*parts))
    anim = f"{slug}_loop.webp"
    figs.save_webp_loop(f.path(anim), loop, frame_ms)
    anim_caption = ("ground truth | hybrid" if has_gt else "hybrid") + \
        f", {len(frames)} frames ({frames[0]}..{frames[-1]}, every {stride}), {frame_ms} ms each, looping"
    cam_name = view.render.get("cameras", ["?"])[cam]
    head = (f"<h3>{html.escape(view.motion)}</h3><p class='note'>frame {t} of {view.run.get('frames', '?')}, camera "
            f"{html.escape(str(cam_name))}, garment crop {box[3] - box[2]}x{box[1] - box[0]} px enlarged x{k} "
            f"(nearest neighbour); far field: {html.escape(str(view.render.get('far_source', '?')))}, kernel "
            f"{view.render.get('kernel_size', '?')} px</p>")
    return (head + f"<div class='strip'>{''.join(cells)}</div><div class='strip'>{''.join(heat)}</div>"
            + detail + f"<h4>Decomposition: hybrid = l(S) + h(G)</h4><div class='strip'>{''.join(dec)}</div>"
            f"<h4>In motion</h4><div class='strip'>{f.img(anim, anim_caption, 'anim')}</div>"
            + _relight_section(view, preds, box, k, f, slug, frame_ms))


@dataclass
class TruthStrip:
    """One run's middle frame, camera 0: ground truth under the frames' light | 3DGS-only | PBR-only | hybrid
    (``cells``) and an error heatmap per variant (``heat``), cropped to the garment box ``box`` enlarged ``k``
    times; with every rendered frame (``preds``) and its truth (``gts``, None where there is none)."""

    preds: list[dict[str, np.ndarray]]
    gts: list[np.ndarray | None]
    box: tuple[int, int, int, int]
    k: int
    frame: int
    layers: dict[str, np.ndarray | None]
    cells: list[str]
    heat: list[str]


def _truth_strip(view: RunView, f: _Figures, slug: str, cam: int = 0) -> TruthStrip:
    frames = view.frames
    preds = [dict(np.load(view.folder / "render" / f"frame_{t:04d}.npz")) for t in frames]
    light = render_light_record(view)
    gts = [None if light is None else ground_truth_frame(view.folder, t, light) for t in frames]
    coverage = [p[k][cam] for p in preds for k in ("alpha", "pbr_alpha", "hybrid_alpha") if k in p]
    coverage += [g[cam].max(-1) for g in gts if g is not None]
    box = figs.garment_box(coverage)
    k = figs.enlarge_factor(box)
    mid = len(frames) // 2
    t, pred, gt = frames[mid], preds[mid], gts[mid]
    layers = {"gt": None if gt is None else gt[cam], "3dgs_only": pred["near"][cam], "pbr_only": pred["pbr"][cam],
              "hybrid": pred["hybrid"][cam]}
    heat = [f"<figure style='width:{(box[3] - box[2]) * k}px'><img src='{FIGURES}/error_scale.svg' "
            "alt='heatmap colour scale' style='width:100%'><figcaption>error heatmaps below each variant: 0 to "
            f"{figs.ERROR_MAX} linear RGB</figcaption></figure>"] if gt is not None else []
    cells = _crop_cells(layers, box, k, f, f"{slug}_{t:04d}")
    measured = view.metrics if metrics_under_render_light(view) else None
    for key, label in STRIP:
        if layers[key] is not None and key != "gt" and gt is not None:
            hname = f"{slug}_{t:04d}_{key}_error.png"
            figs.save_png(f.path(hname), figs.heatmap_rgb8(figs.crop(layers[key], box, k), figs.crop(gt[cam], box, k)))
            psnr = (measured or {}).get(key, {}).get("psnr")
            heat.append(f.img(hname, f"{label} error" + (f" (PSNR {psnr:.2f} dB, motion mean)" if psnr else ""),
                              "crop"))
    if gt is None and is_relit(view):
        heat.append("<p class='note'>No ground truth under this run's light yet: <code>pgc eval RUN --gt "
                    "CAPTURE</code> renders it (for a synthetic capture), and the error heatmaps follow.</p>")
    elif gt is None:
        heat.append("<p class='note'>No ground truth for this run: error heatmaps need a synthetic capture "
                    "(<code>pgc eval RUN CAPTURE</code> renders it).</p>")
    return TruthStrip(preds, gts, box, k, t, layers, cells, heat)


def _crop_cells(layers: dict[str, np.ndarray | None], box: tuple[int, int, int, int], k: int, f: _Figures,
                stem: str) -> list[str]:
    """One enlarged crop per layer of :data:`STRIP` that is present, written as ``STEM_KEY.png``."""
    cells = []
    for key, label in STRIP:
        if layers[key] is not None:
            name = f"{stem}_{key}.png"
            figs.save_png(f.path(name), figs.to_rgb8(figs.crop(layers[key], box, k)))
            cells.append(f.img(name, label, "crop"))
    return cells


def _detail_section(layers: dict[str, np.ndarray | None], pred: dict[str, np.ndarray], cam: int, f: _Figures,
                    stem: str) -> str:
    """Close-ups of the garment where the ground truth (else the hybrid) holds the most fine detail: the same
    windows of every variant, enlarged so that ribs, seams and pocket edges a few pixels wide can be seen."""
    from scipy.ndimage import binary_erosion

    source = layers["gt"] if layers["gt"] is not None else layers["hybrid"]
    alpha = pred.get("hybrid_alpha", pred.get("alpha"))[cam]
    inside = np.asarray(alpha) > 0.5
    if layers["gt"] is not None:
        inside &= np.asarray(layers["gt"]).max(-1) > 0
    inside = binary_erosion(inside, iterations=2)
    windows = figs.detail_windows(source, inside)
    if not windows:
        return ""
    k = max(1, figs.DETAIL_TARGET // figs.DETAIL_SIZE)
    rows = []
    for i, box in enumerate(windows):
        cells = _crop_cells(layers, box, k, f, f"{stem}_detail{i}")
        rows.append(f"<p class='note'>rows {box[0]}-{box[1]}, columns {box[2]}-{box[3]}, enlarged x{k}</p>"
                    f"<div class='strip'>{''.join(cells)}</div>")
    what = "ground truth" if layers["gt"] is not None else "hybrid"
    return (f"<h4>Detail: the {len(windows)} windows of {figs.DETAIL_SIZE} px with the most fine detail in the "
            f"{what}</h4>" + "".join(rows))


def is_relit(view: RunView) -> bool:
    """Whether the run was rendered under another light than the capture's (an environment map or rotating)."""
    light = view.render.get("light", {})
    return bool(light.get("rotating") or light.get("envmap"))


def metrics_under_render_light(view: RunView) -> bool:
    """Whether the run's metrics compare its frames with ground truth lit as they were: ``metrics.json`` records
    the same light as ``render.json``; metrics that record no light count only for an unrelit run."""
    from pgc.io.light_record import capture_record, same_light

    measured = (view.metrics or {}).get("light")
    if not isinstance(measured, dict):
        return not is_relit(view)
    rendered = view.render.get("light")
    if not (isinstance(rendered, dict) and "kind" in rendered):
        rendered = None if is_relit(view) else capture_record()
    return rendered is not None and same_light(measured, rendered, view.frames)


def _relight_section(view: RunView, preds: list[dict], box, k: int, f: _Figures, slug: str, frame_ms: int) -> str:
    if not view.render.get("light", {}).get("rotating"):
        return ""
    pick = sorted(set(np.linspace(0, len(preds) - 1, min(RELIGHT_FRAMES, len(preds))).round().astype(int)))
    cells = []
    for i in pick:
        name = f"{slug}_relight_{view.frames[i]:04d}.png"
        figs.save_png(f.path(name), figs.to_rgb8(figs.crop(preds[i]["hybrid"][0], box, k)))
        cells.append(f.img(name, f"light at {360.0 * i / len(preds):.0f} deg", "crop small"))
    anim = f"{slug}_relight.webp"
    figs.save_webp_loop(f.path(anim), [figs.to_rgb8(figs.crop(p["hybrid"][0], box, k)) for p in preds], frame_ms)
    return (f"<h4>Relighting: the environment turns 360 degrees about +Y</h4><div class='strip'>{''.join(cells)}"
            f"{f.img(anim, 'rotating light, looping', 'crop small')}</div>")


def _light_means(views: list[RunView]) -> dict[str, dict[str, float]] | None:
    """Variant -> metric -> mean over the runs whose metrics were measured against truth under their own
    light (None when there are none)."""
    measured = [v.metrics for v in views if v.metrics and metrics_under_render_light(v)
                and all(key in v.metrics for key in VARIANTS)]
    if not measured:
        return None
    names = [n for n in measured[0]["hybrid"] if n != "per_frame"]
    return {key: {n: float(np.mean([m[key][n] for m in measured])) for n in names} for key in VARIANTS}


def _lights_table(means: dict[str, dict[str, dict[str, float]]]) -> str:
    """Variant x light: every metric (mean over motions), and the change of each PSNR (plain and at a fixed
    exposure) from the capture light."""
    lights = list(means)
    names = list(next(iter(means.values()))["hybrid"])
    head = "".join(f"<th>{html.escape(light)} {html.escape(n)}</th>" for light in lights for n in names)
    base = means.get("capture")
    deltas = [n for n in PSNR_NAMES if n in names] if base else []
    novel = [light for light in lights if light != "capture"]
    delta_head = "".join(f"<th>{html.escape(light)} &Delta;{html.escape(n)}</th>" for n in deltas for light in novel)
    rows = []
    for key, label in STRIP[1:]:
        cells = "".join(f"<td>{means[light][key][n]:.4f}</td>" for light in lights for n in names)
        cells += "".join(f"<td>{means[light][key][n] - base[key][n]:+.2f} dB</td>" for n in deltas for light in novel)
        rows.append(f"<tr><td>{html.escape(label)}</td>{cells}</tr>")
    return f"<table><tr><th>variant</th>{head}{delta_head}</tr>{''.join(rows)}</table>"


def _lights_section(relit: dict[str, list[RunView]], captured: list[RunView], f: _Figures) -> str:
    """Per novel light: each motion's relit frames next to ground truth under the same light, with error
    heatmaps; then the variant x light table."""
    from pgc.io.light_record import describe
    from pgc.pipeline.relight import EVAL_LIGHTS

    if not relit:
        return ""
    parts = ["<h2>Under novel lights</h2><p class='note'>Each motion rendered again under each light (its relit "
             "run, <code>RUN/relit/LIGHT/</code>: <code>pgc render</code> with <code>--light FILE "
             "--light-rotation DEG</code>), next to ground truth rendered with the true material under the same "
             "light on the same geometry. The Gaussians of the near field keep the colours they were fitted "
             "under; only the far field is relit.</p>"]
    relit_motions = {v.motion for views in relit.values() for v in views}
    means = {"capture": _light_means([v for v in captured if v.motion in relit_motions])}  # like with like
    for name, views in relit.items():
        light = EVAL_LIGHTS.get(name)
        record = render_light_record(views[0]) if views else None
        parts.append(f"<h3>{html.escape(name)}: {html.escape(light.description if light else name)}</h3>"
                     f"<p class='note'>{html.escape(describe(record))}</p>")
        for view in views:
            strip = _truth_strip(view, f, f"{name}_{view.motion.replace('/', '_')}")
            parts.append(f"<h4>{html.escape(view.motion)}, frame {strip.frame}</h4><div class='strip'>"
                         f"{''.join(strip.cells)}</div><div class='strip'>{''.join(strip.heat)}</div>")
        means[name] = _light_means(views)
    measured = {k: v for k, v in means.items() if v is not None}
    if measured:
        parts.append("<h3>Metrics per light</h3><p class='note'>Mean over the motions evaluated under the novel "
                     f"lights ({html.escape(', '.join(sorted(relit_motions)))}), each against truth under its own "
                     "light, restricted to the garment; &Delta;PSNR: the change from the capture light on the same "
                     "motions.</p>" + _lights_table(measured))
    return "".join(parts)


def _metric_table(per_motion: dict[str, dict[str, dict[str, float]]]) -> str:
    variants = list(next(iter(per_motion.values())))
    names = list(next(iter(per_motion.values()))[variants[0]])
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    rows = "".join(f"<tr><td>{html.escape(m)}</td><td>{html.escape(v)}</td>"
                   + "".join(f"<td>{r[v][n]:.4f}</td>" for n in names) + "</tr>"
                   for m, r in per_motion.items() for v in variants)
    return f"<details><summary>the numbers</summary><table><tr><th>motion</th><th>variant</th>{head}</tr>{rows}" \
           "</table></details>"


def _bench_records(bench: Path | None) -> list[dict[str, Any]]:
    if bench is None:
        return []
    path = bench / "bench.json" if bench.is_dir() else bench
    if not path.is_file():
        raise PGCDataError(f"{bench}: no bench.json; make one with 'pgc bench --out DIR' and pass that DIR")
    data = read_json(path, "bench.json", fix="rerun 'pgc bench'")
    records = data.get("records", data) if isinstance(data, dict) else data
    if not isinstance(records, list):
        raise PGCDataError(f"{path}: expected a list of bench records (or an object with 'records')")
    return [r for r in records if isinstance(r, dict)]


CSS = """body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1500px;padding:0 1em;color:#222}
h2{border-bottom:1px solid #ddd;padding-bottom:2px;margin-top:1.6em} h3{margin:1.2em 0 .2em} h4{margin:.8em 0 .3em}
.strip{display:flex;gap:8px;flex-wrap:wrap;align-items:flex-start} figure{margin:0;width:min-content}
img.crop,img.anim{image-rendering:pixelated;background:#000} img.small{height:120px}
figcaption{font-size:12px;text-align:center;color:#444;max-width:320px} .note{color:#555;font-size:13px}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
code{background:#f3f3f3;padding:0 3px} #load-check{font-size:12px;color:#555}
figure.view3d{width:min(100%,720px)} model-viewer{width:100%;height:540px;background:#f4f4f4}
figure.view3d figcaption{max-width:none;text-align:left}"""

LOAD_CHECK = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  var p = document.getElementById('load-check');
  p.setAttribute('data-loaded', ok); p.setAttribute('data-total', imgs.length);
  p.textContent = ok === imgs.length ? 'all ' + ok + ' pictures loaded'
    : (imgs.length - ok) + ' of ' + imgs.length + ' pictures failed to load (missing files in report/?)';
});
</script>"""


def build_report(out: Path, title: str, views: list[RunView], summary: dict[str, Any],
                 bench: Path | None = None, relit: dict[str, list[RunView]] | None = None) -> dict[str, Any]:
    """Write ``out/report.html`` and ``out/report/``; returns {path, files, bytes}. ``summary``: the demo's
    metrics.json (``preset``, ``seconds``, ``stages``, ``config``; per-motion metrics come from ``views``).
    ``relit``: light name -> the relit runs of ``views`` under it (:mod:`pgc.pipeline.relight`)."""
    out = Path(out)
    if not views:
        raise PGCDataError(f"{out}: no rendered runs to report; run 'pgc demo' or 'pgc render RUN' first")
    f = _Figures(out)
    sections = "".join(_motion_section(v, f) for v in views)
    lights = _lights_section(relit or {}, views, f)
    per_motion = {v.motion: {key: {n: x for n, x in v.metrics[key].items() if n != "per_frame"} for key in VARIANTS}
                  for v in views if v.metrics and metrics_under_render_light(v)
                  and all(key in v.metrics for key in VARIANTS)}
    charts = []
    if per_motion:
        from pgc.io.light_record import describe

        lit = {}  # light -> motions
        for v in views:
            if v.motion in per_motion:
                lit.setdefault(describe(v.metrics.get("light", {"kind": "capture"})), []).append(v.motion)
        figs.metrics_chart(f.path("metrics.svg"), per_motion)
        charts.append(f"<h2>Metrics per motion</h2><p class='note'>Restricted to the garment (mean over rendered "
                      "frames and cameras). PSNR, SSIM, FSIM: higher is better; LPIPS: lower. Ground truth lit as "
                      "the frames: " + "; ".join(f"{html.escape(k)} ({html.escape(', '.join(m))})"
                                                 for k, m in lit.items()) + ".</p>"
                      f"{f.img('metrics.svg', 'metrics per motion and variant')}{_metric_table(per_motion)}")
    else:
        why = ("Relit: no metrics against ground truth under the frames' light yet; <code>pgc eval RUN --gt "
               "CAPTURE</code> renders it." if all(map(is_relit, views))
               else "Not evaluated: <code>pgc eval RUN CAPTURE</code> writes RUN/metrics.json.")
        charts.append(f"<h2>Metrics</h2><p class='note'>{why}</p>")
    stages, steps = summary.get("stages", {}), summary.get("seconds", {})
    if stages or steps:
        preset = f", preset '{summary['preset']}'" if summary.get("preset") else ""
        figs.timings_chart(f.path("timings.svg"), {"reconstruction stages": stages,
                                                   "pipeline steps" + (" (all motions)" if len(views) > 1 else ""):
                                                   steps}, f"ours, this machine{preset}")
        charts.append("<h2>Timings</h2><p class='note'>Wall-clock seconds measured on this machine for the whole "
                      "run, not per frame. The paper's per-frame efficiency table (RTX 3090) is not reproduced "
                      "here: the chart shows only our measurements.</p>" + f.img("timings.svg", "stage timings"))
    records = _bench_records(bench)
    if records and figs.bench_chart(f.path("bench.svg"), records):
        charts.append(f"<h2>Speed against error</h2><p class='note'>From {len(records)} <code>pgc bench</code> "
                      "records: one panel per role; lower-left is better.</p>"
                      + f.img("bench.svg", "seconds against error per implementation"))
    else:
        charts.append("<h2>Speed against error</h2><p class='note'>No bench records: run <code>pgc bench --out "
                      "DIR</code>, then <code>pgc report FOLDER --bench DIR</code>.</p>")
    if any(f_.name.endswith("_error.png") for f_ in f.written):
        figs.colourbar_svg(f.path("error_scale.svg"))
    relit_shown = bool(relit) or any(v.render.get("light", {}).get("rotating") for v in views)
    relight_note = "" if relit_shown else (
        "<p class='note'>No relit run here. Make one with <code>pgc render RUN --light sky.exr --rotate-light</code>"
        " (the environment turns 360 degrees over the frames; a synthetic capture ships environment maps in "
        "<code>CAPTURE/ground_truth/envmaps/</code>), then <code>pgc report RUN</code>. Rendering replaces the "
        "run's frames: relight a copy of the run folder.</p>")
    view3d = view_section(views[0].folder, _asset_folder(out, views[0]), views[0].run, views[0].motion, FIGURES,
                          f.path)
    f.sweep()
    sizes = sum(p.stat().st_size for p in f.written)
    config = summary.get("config")
    config_html = (f"<details><summary>resolved configuration</summary><pre>{html.escape(json.dumps(config, indent=1))}"
                   "</pre></details>" if config else "")
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>{CSS}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Novel poses of the garment, rendered by the hybrid renderer (I = h(G) + l(S)) and its two ablations, next to
ground truth rendered with the true material on the same simulated geometry. Each picture is cut to the garment
and enlarged by whole pixels (nearest neighbour), so every rendered pixel is visible.</p>
<p id="load-check">pictures not checked yet</p>
<h2>Motions</h2>{sections}{relight_note}
{lights}
{view3d}
{''.join(charts)}
{config_html}
<p class='note'>This report: report.html and {len(f.written)} files in {FIGURES}/ ({{size}}); relative links only, opens
from disk.</p>
{LOAD_CHECK}
</body></html>"""
    total = sizes + len(page.encode())
    page = page.replace("{size}", f"{total / 1024:.0f} KiB in all")
    path = out / "report.html"
    write_text(path, page)
    return {"path": str(path), "files": len(f.written) + 1, "bytes": total}


def write_report(out: str | Path, summary: dict[str, Any], results: dict[str, dict[str, Any]]) -> Path:
    """The demo's report: ``OUT/report.html`` from the evaluated runs of ``results`` (motion -> eval result)."""
    out = Path(out)
    views = [read_run_view(_run_folder(out, motion, res), motion) for motion, res in results.items()]
    build_report(out, f"PGC demo: preset '{summary.get('preset')}'", views, summary, relit=relit_views(views))
    return out / "report.html"


def relit_views(views: list[RunView]) -> dict[str, list[RunView]]:
    """Light name -> the rendered relit runs of ``views`` under it (:func:`pgc.pipeline.relight.light_folders`)."""
    from pgc.pipeline.relight import light_folders

    out: dict[str, list[RunView]] = {}
    for view in views:
        for name, folder in light_folders(view.folder).items():
            if name != "capture":
                out.setdefault(name, []).append(read_run_view(folder, view.motion))
    return out


def _asset_folder(out: Path, view: RunView) -> Path:
    """The asset of ``view``: OUT/asset when OUT is a demo folder (which may have moved), else the recorded one."""
    from pgc.io.asset import MANIFEST

    local = out / "asset"
    return local if (local / MANIFEST).is_file() else Path(str(view.run.get("asset")))


def _run_folder(out: Path, motion: str, result: dict[str, Any]) -> Path:
    """The run of ``motion``: OUT/runs/MOTION when present (the folder may have moved), else the recorded path."""
    local = out / "runs" / motion
    return local if (local / "run.json").is_file() else Path(result["run"])


def report_folder(folder: str | Path, bench: str | Path | None = None) -> dict[str, Any]:
    """``pgc report``: the report of a demo folder (``metrics.json`` + ``runs/``) or of one rendered run."""
    folder = Path(folder)
    bench_path = Path(bench) if bench else None
    if not folder.is_dir():
        raise PGCDataError(f"{folder}: not a folder; give a demo output folder (pgc demo --out) or a run folder "
                           "(pgc animate, then pgc render)")
    if (folder / "run.json").is_file():
        view = read_run_view(folder)
        summary = _run_summary(view)
        return build_report(folder, f"PGC run: {view.motion}", [view], summary, bench_path, relit_views([view]))
    metrics = folder / "metrics.json"
    if not (folder / "runs").is_dir():
        raise PGCDataError(f"{folder}: neither a run folder (no run.json) nor a demo folder (no runs/); give the "
                           "folder written by 'pgc demo --out' or 'pgc animate'")
    summary = read_json(metrics, "metrics.json") if metrics.is_file() else {}
    runs = sorted(p for p in (folder / "runs").iterdir() if (p / "render" / "render.json").is_file())
    order = list(summary.get("motions", {}))
    runs.sort(key=lambda p: order.index(p.name) if p.name in order else len(order))
    views = [read_run_view(p, p.name) for p in runs]
    return build_report(folder, f"PGC demo: preset '{summary.get('preset', '?')}'", views, summary, bench_path,
                        relit_views(views))


def _run_summary(view: RunView) -> dict[str, Any]:
    """Timings of a single run: the asset's stage seconds and the simulation's (their ``timings.json``)."""
    from pgc.io.timings import read_timings

    stages = read_timings(view.run["asset"]).get("seconds", {}) if isinstance(view.run.get("asset"), str) else {}
    stages = {k: v for k, v in stages.items() if isinstance(v, (int, float))}
    sim = read_timings(view.folder).get("seconds")
    return {"stages": stages, "seconds": {"simulate": sim} if isinstance(sim, (int, float)) else {}}
