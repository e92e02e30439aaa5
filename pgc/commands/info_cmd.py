"""``pgc info``: what an asset or a run folder holds."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pgc.commands._common import emit, read_json_object

EPILOG = """\
examples:
  pgc info runs/demo-default/asset            meshes, Gaussians, BRDF and parameters, light, figures
  pgc info runs/demo-default/runs/spooky      the run (motion, frames, simulator, render, metrics) + its asset
  pgc info runs/demo-default/asset --json     the same as JSON
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info", help="show what an asset or run folder holds",
        description="Print the contents of a garment asset (mesh sizes, Gaussian count and SH degree, BRDF and "
                    "its fitted parameters, light, measured figures, stage timings, provenance: package versions, "
                    "source capture) or of a run (motion, frames, fps, simulator, rendering, metrics, and its "
                    "asset). Reads files only; computes nothing.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", help="asset folder (with manifest.json) or run folder (with run.json)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=run)


def asset_info(asset, folder: Path) -> dict[str, Any]:
    from pgc.io.asset import read_manifest
    from pgc.io.timings import read_timings

    manifest = read_manifest(folder)
    g, b = asset.garment, asset.body
    texture = asset.material.base_color
    light = asset.light
    return {
        "folder": str(folder),
        "garment": {"vertices": len(g.vertices), "faces": len(g.faces), "uv": 0 if g.uv is None else len(g.uv)},
        "body": {"vertices": len(b.vertices), "faces": len(b.faces)},
        "gaussians": {"count": len(asset.gaussians), "sh_degree": asset.gaussians.sh_degree},
        "material": {"brdf": asset.material.brdf, "params": asset.material.params,
                     "base_color": None if texture is None else list(texture.shape[:2])},
        "light": {"radiance": light.radiance.tolist(), "rotation_deg": light.rotation_deg,
                  "envmap": None if light.envmap is None else list(light.envmap.shape[:2])},
        "figures": asset.figures,
        "timings": read_timings(folder),
        "provenance": {"versions": manifest.get("versions", {}),
                       "source": asset.config.get("source", {}), "files": manifest.get("files", {})},
    }


def run_info(folder: Path, run: dict[str, Any], frames: int) -> dict[str, Any]:
    out: dict[str, Any] = {"folder": str(folder), "motion": run.get("motion"), "frames": frames,
                           "fps": run.get("fps"), "simulator": run.get("simulator"),
                           "simulation": {k: v for k, v in run.get("figures", {}).items() if not isinstance(v, list)}}
    render = folder / "render" / "render.json"
    if render.is_file():
        meta = read_json_object(render, f"render the run again with 'pgc render {folder}'")
        out["render"] = {k: meta.get(k) for k in ("frames", "cameras", "kernel_size", "far_source", "light")}
    metrics = folder / "metrics.json"
    if metrics.is_file():
        m = read_json_object(metrics, f"evaluate the run again with 'pgc eval {folder} --gt CAPTURE'")
        out["metrics"] = {k: {n: x for n, x in v.items() if n != "per_frame"} for k, v in m.items()
                          if isinstance(v, dict) and "per_frame" in v}
        out["metrics_light"] = m.get("light")
    return out


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and all(isinstance(v, (int, float)) for v in value):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    return str(value)


def as_text(info: dict[str, Any]) -> str:
    from pgc.io.light_record import describe

    lines = []
    if "motion" in info:
        lines += [f"run {info['folder']}", f"  motion {info['motion']}: {info['frames']} frames at {info['fps']} fps, "
                  f"simulator {info['simulator']}"]
        lines += [f"  simulation {k}: {_fmt(v)}" for k, v in info["simulation"].items()]
        if "render" in info:
            r = info["render"]
            light = r["light"] if isinstance(r.get("light"), dict) else {}
            kind = ("environment map" if light.get("envmap") else "fitted capture light") + \
                (", rotating 360 deg" if light.get("rotating") else "")
            if light.get("kind") == "envmap":
                kind = describe(light)
            lines.append(f"  rendered frames {r['frames']} from cameras {r['cameras']}, kernel {r['kernel_size']} px, "
                         f"far field {r['far_source']}, {kind}")
        else:
            lines.append("  not rendered yet (pgc render RUN)")
        if info.get("metrics"):
            lines.append(f"  metrics against ground truth lit by {describe(info.get('metrics_light'))}")
        for variant, vals in info.get("metrics", {}).items():
            lines.append(f"  {variant:>10}: " + "  ".join(f"{k}={_fmt(v)}" for k, v in vals.items()))
        info = info["asset"]
    m, p = info["material"], info["provenance"]
    lines += [f"asset {info['folder']}",
              f"  garment mesh: {info['garment']['vertices']} vertices, {info['garment']['faces']} faces, "
              f"{info['garment']['uv']} UVs",
              f"  body mesh: {info['body']['vertices']} vertices, {info['body']['faces']} faces",
              f"  gaussians: {info['gaussians']['count']}, SH degree {info['gaussians']['sh_degree']}",
              f"  brdf {m['brdf']}: " + ", ".join(f"{k}={_fmt(v)}" for k, v in m["params"].items()),
              f"  base colour texture: {m['base_color']}",
              f"  light: radiance {_fmt(info['light']['radiance'])}, rotation {info['light']['rotation_deg']} deg, "
              f"envmap {info['light']['envmap']}"]
    seconds = info.get("timings", {}).get("seconds", {})
    if isinstance(seconds, dict) and seconds:  # timings.json is informative: what is not a number is left out
        lines.append("  stage seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in seconds.items()
                                                     if isinstance(v, (int, float))))
    for stage, figs in info["figures"].items():
        if isinstance(figs, dict):
            scalars = {k: v for k, v in figs.items() if isinstance(v, (int, float, str))}
            if scalars:
                lines.append(f"  {stage}: " + ", ".join(f"{k}={_fmt(v)}" for k, v in scalars.items()))
    lines.append("  written with " + ", ".join(f"{k} {v}" for k, v in p["versions"].items()))
    if p["source"]:
        lines.append("  source: " + ", ".join(f"{k} {v}" for k, v in p["source"].items()))
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from pgc.commands.export_cmd import load_source

    kind, asset, anim, meta = load_source(args.source)
    folder = Path(args.source)
    info = asset_info(asset, Path(meta["asset"]) if kind == "run" else folder)
    if kind == "run":
        info = {**run_info(folder, meta, anim.frames), "asset": info}
    emit(args, info, as_text(info))
    return 0
