"""``pgc export``: an asset or an animated run as glTF, USD, per-frame 3DGS .ply or OBJ sequences."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pgc.checks import naming_output
from pgc.commands._common import check_not_inside, check_out_file, check_out_folder, check_run, emit

EPILOG = """\
examples:
  pgc export runs/demo-default/asset --format gltf --out garment.glb        still garment + capture mesh
  pgc export runs/demo-default/runs/spooky --format gltf --out spooky.glb  animated (morph targets)
  pgc export runs/demo-default/runs/spooky --format usd --out spooky.usda  time-sampled points
  pgc export runs/demo-default/runs/spooky --format ply-seq --out splats/  frame_XXXX.ply for splat viewers
  pgc export runs/demo-default/runs/spooky --format obj-seq --out objs/    garment_XXXX.obj, body_XXXX.obj

The material mapping (our sheen BRDF -> KHR_materials_sheen / UsdPreviewSurface) is in docs/export.md.
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export", help="export an asset or animated run (glTF, USD, 3DGS .ply or OBJ sequences)",
        description="Write a garment asset (pgc reconstruct) or an animated run (pgc animate) in a format that "
                    "graphics tools open: gltf (one .glb: textured garment with the fitted material as "
                    "KHR_materials_sheen, body, the motion as morph targets), usd (.usda/.usdc: time-sampled "
                    "points, UsdPreviewSurface), ply-seq (a folder of standard 3DGS .ply, one per frame) or "
                    "obj-seq (a folder of OBJ meshes per frame). Every file is written atomically.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", help="asset folder (with manifest.json) or run folder (with run.json)")
    p.add_argument("--format", required=True, metavar="{gltf,usd,ply-seq,obj-seq}", help="output format")
    p.add_argument("--out", required=True, help="output file (.glb; .usda/.usdc/.usd) or folder (ply-seq, obj-seq)")
    p.add_argument("--json", action="store_true", help="print the written files as JSON")
    p.set_defaults(func=run)


def load_source(path: str | Path) -> tuple[str, Any, Any, dict[str, Any]]:
    """(kind 'asset' or 'run', the asset, its Animation, the run.json or {}) of an asset or run folder."""
    import numpy as np

    from pgc.errors import PGCDataError
    from pgc.io.asset import MANIFEST, read_asset
    from pgc.io.export import Animation

    path = Path(path)
    if not path.is_dir():
        raise PGCDataError(f"{path}: no such folder; give an asset folder (pgc reconstruct --out) or a run "
                           "folder (pgc animate)")
    if (path / MANIFEST).is_file():
        asset = read_asset(path)
        return "asset", asset, Animation.still(asset), {}
    if not (path / "run.json").is_file():
        raise PGCDataError(f"{path}: neither an asset folder (no {MANIFEST}) nor a run folder (no run.json); give "
                           "the folder written by 'pgc reconstruct' or 'pgc animate'")
    run = check_run(path)
    asset_dir = Path(run["asset"])
    asset = read_asset(asset_dir)
    garment = np.load(path / "garment.npz")["vertices"]
    if garment.ndim != 3 or garment.shape[1] != len(asset.garment.vertices):
        raise PGCDataError(f"{path / 'garment.npz'}: vertices {garment.shape} do not fit the asset's garment "
                           f"({len(asset.garment.vertices)} vertices); rerun 'pgc animate' on this asset")
    with np.load(path / "body.npz") as z:
        body, faces = z["vertices"], z["faces"]
    return "run", asset, Animation(garment, body, faces, float(run.get("fps", 30.0))), run


def check_out(fmt: str, out: str) -> None:
    """The format and the output path (suffix, writable, not inside an asset) before any reading."""
    from pgc.errors import PGCDataError
    from pgc.io.export import FORMATS, USD_SUFFIXES

    if fmt not in FORMATS:
        raise PGCDataError(f"--format {fmt!r}: unknown export format; use one of {', '.join(FORMATS)}")
    if fmt in ("gltf", "usd"):
        suffixes = (".glb",) if fmt == "gltf" else USD_SUFFIXES
        if Path(out).suffix.lower() not in suffixes:
            raise PGCDataError(f"--out {out}: the {fmt} format writes a {' or '.join(suffixes)} file; name the "
                               f"output PATH{suffixes[0]}")
        check_out_file(out, example=f"garment{suffixes[0]}")
    else:
        check_out_folder(out)


def run(args: argparse.Namespace) -> int:
    from pgc.io.export import export

    check_out(args.format, args.out)
    kind, asset, anim, meta = load_source(args.source)
    asset_dir = meta["asset"] if kind == "run" else args.source
    check_not_inside(args.out, asset_dir, "asset folder")
    with naming_output(args.out):
        files = export(args.format, args.out, asset, anim)
    emit(args, {"source": args.source, "kind": kind, "format": args.format, "frames": anim.frames,
                "files": [str(f) for f in files]},
         f"{args.format}: {anim.frames} frame(s) of the {kind} {args.source} -> {args.out} ({len(files)} file(s))")
    return 0
