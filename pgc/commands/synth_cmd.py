"""``pgc synth``: generate a synthetic capture with ground truth; ``pgc synth render-frames``: render the
ground truth of new garment/body vertex sequences."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

from pgc.errors import PGCDataError

if TYPE_CHECKING:
    from pgc.events import Reporter
    from pgc.roles.scene_renderer import SceneRenderer
    from pgc.stages.eval import EvalSettings

USAGE = """\
pgc synth OUT [--preset tiny|default|cotton|large|knit] [--garment tshirt|dress] [--fabric NAME]
          [--framing body|garment] [--detail none|relief|seams] [--fit loose|resting] [--seed N] [--config FILE]
pgc synth render-frames CAPTURE GARMENT_NPZ BODY_NPZ OUT_DIR [--spp N] [--config FILE]"""

EPILOG = """\
forms:
  pgc synth OUT                 a capture folder (transforms.json, images, masks, segmentation, background,
                                extras/linear, extras/albedo, extras/depth), OUT/ground_truth/ and
                                OUT/contact_sheet.png
  pgc synth render-frames CAPTURE GARMENT_NPZ BODY_NPZ OUT_DIR
                                renders the capture's ground-truth materials on new vertices
                                (.npz files with key 'vertices' (T, V, 3), the topology of
                                CAPTURE/ground_truth/garment.obj and body.obj) from the capture's cameras;
                                writes OUT_DIR/frame_####.npz (color, alpha, garment_mask, segmentation,
                                spp and noise per camera) and one sRGB PNG per frame and camera; sampled
                                as pgc eval's truth: passes of [stages.eval] gt_spp samples until the
                                garment's relative noise is gt_noise or gt_max_spp samples are spent

presets: tiny (6 views, 64 px, seconds)
         default (the demo: 128 views at 192 px framing the garment; a striped cotton tee (the cotton fibre
           truth) resting on the body, with seams, ribbed hems, a patch pocket and folds as geometry)
         cotton (the earlier default: 128 views at 256 px of the whole body; the same tee, loose, no detail)
         large (64 views, 1024 px, whole body)
         knit (32 views, 320 px, garment framing: a rib-knit (pgc-sheen) tee resting on the body with knit
           relief, ribbed bands, seams, a patch pocket and folds as geometry, and fibre fuzz)
fabrics: fibre truths (a Lambertian surface under a layer of fibres shaded by a fibre scattering model):
           cotton, fleece, knit, velvet, satin
         in-family controls (the BRDFs the material fit chooses from): cotton-sheen, fleece-sheen,
           knit-sheen, rib-knit-sheen, satin-sheen (pgc-sheen), lambertian
details: none (the simulation mesh), relief (knit wales, ribbed bands, seams, pocket, folds), seams (the same
         without the knit wales)
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("synth", help="generate a synthetic capture with ground truth", usage=USAGE,
                       description="Generate a synthetic multi-view capture of a clothed body (rendered by the "
                                   "configured scene_renderer; default: Mitsuba path tracing on the CPU) with "
                                   "complete ground truth: meshes, materials, textures, light, body model and "
                                   "motions, albedo and depth per view.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="+", metavar="OUT", help="output folder (or 'render-frames' and its paths)")
    p.add_argument("--preset", default="default", help="tiny, default, cotton, large or knit (default: default)")
    p.add_argument("--garment", default=None, help="tshirt or dress (default: the preset's)")
    p.add_argument("--fabric", default=None, help="a fibre truth (cotton, fleece, knit, velvet, satin) or an "
                                                  "in-family control (cotton-sheen, fleece-sheen, knit-sheen, "
                                                  "rib-knit-sheen, satin-sheen, lambertian) (default: the preset's)")
    p.add_argument("--detail", default=None, help="near-field geometry: none, relief or seams (default: the "
                                                  "preset's)")
    p.add_argument("--fit", default=None, help="loose or resting (hangs from the shoulders) (default: the "
                                               "preset's)")
    p.add_argument("--framing", default=None, choices=("body", "garment"),
                   help="what the cameras frame: the whole body or the garment (default: the preset's)")
    p.add_argument("--capture-light", default=None,
                   help="the dome's light, recorded in the capture for the material fit: uniform (a constant "
                        "environment) or sky-sun (a sky and a sun: identifies the sheen; docs/pbr.md) "
                        "(default: the preset's)")
    p.add_argument("--seed", type=int, default=0, help="random seed; the same seed gives identical files")
    p.add_argument("--looseness", type=float, default=None,
                   help="garment clearance from the body, metres (resting fit: at the waist) (default: the preset's)")
    p.add_argument("--views", type=int, default=None, help="override the preset's number of cameras")
    p.add_argument("--resolution", type=int, default=None, help="override the preset's image size, pixels")
    p.add_argument("--spp", type=int, default=None, help="override the path-tracing samples per pixel")
    p.add_argument("--config", metavar="FILE", help="run configuration TOML: its [scene_renderer] renders "
                                                     "(default: the built-in defaults)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pgc.checks import naming_output
    from pgc.commands._common import check_out_folder, discover, load_config
    from pgc.events import Reporter
    from pgc.progress import ProgressPrinter
    from pgc.synth.render import scene_renderer

    frames = args.paths[0] == "render-frames"
    if frames and len(args.paths) != 5:
        raise PGCDataError(f"render-frames needs CAPTURE GARMENT_NPZ BODY_NPZ OUT_DIR; usage:\n{USAGE}")
    if not frames and len(args.paths) != 1:
        raise PGCDataError(f"expected one output folder, got {args.paths}; usage:\n{USAGE}")
    if not frames:
        check_out_folder(args.paths[0], option="OUT")
    registry = discover(args)
    registry.plugin_manager.register(ProgressPrinter(), name="progress")
    reporter = Reporter(registry.hook)
    cfg = load_config(args, registry)
    if frames:
        return _render_frames(args, reporter, scene_renderer(cfg), cfg.stage("eval"))
    from pgc.synth.generate import generate, get_preset

    preset = get_preset(args.preset, views=args.views, resolution=args.resolution, spp=args.spp,
                        framing=args.framing)
    renderer = scene_renderer(cfg)
    with naming_output(args.paths[0]):
        capture = generate(args.paths[0], preset, garment=args.garment, fabric=args.fabric, seed=args.seed,
                           looseness=args.looseness, reporter=reporter, detail=args.detail, fit=args.fit,
                           capture_light=args.capture_light, renderer=renderer, body_model=cfg.create("body_model"))
    summary = {"out": capture.root, "views": len(capture.views), "resolution": preset.resolution,
               "spp": preset.spp, "contact_sheet": f"{capture.root}/contact_sheet.png",
               "ground_truth": f"{capture.root}/ground_truth", "seconds": reporter.timings}
    print(json.dumps(summary, indent=2) if args.json else
          f"wrote {summary['views']} views to {summary['out']}; look at {summary['contact_sheet']}")
    return 0


def _render_frames(args: argparse.Namespace, reporter: Reporter, renderer: SceneRenderer, settings: EvalSettings) -> int:
    """``render-frames``, sampled as ``pgc eval`` samples its truth (``settings``: the eval stage's; --spp
    overrides the samples of a pass)."""
    from pgc.synth.frames import render_frames_files

    _, capture, garment, body, out = args.paths
    written = render_frames_files(capture, garment, body, out, spp=args.spp or settings.gt_spp, reporter=reporter,
                                  renderer=renderer, noise=settings.gt_noise, max_spp=settings.gt_max_spp)
    print(json.dumps({"frames": [str(p) for p in written]}, indent=2) if args.json else
          f"wrote {len(written)} frames to {out}")
    return 0
