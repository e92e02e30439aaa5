"""The report's interactive 3D view: a run's simulated garment on its body, animated, in @google/model-viewer.

The viewer is vendored by ``scripts/setup.sh`` (``npm ci`` in ``pgc/report_viewer/``, pinned by its
``package-lock.json``); the report copies its one-file UMD bundle and the licences of what it bundles into the
report folder. A page opened from disk may not fetch the files beside it (Chromium and Firefox refuse
``fetch`` of ``file://``), so the run's glTF export travels as a classic script, ``MOTION_3d.js``: the ``.glb``
in base64, which the page decodes (through a ``data:`` URL) into a ``blob:`` URL for the viewer. The viewer's
default decoder locations (Draco, KTX2, Lottie: a CDN) are pointed at the report folder before the element is
built; the export uses none of those encodings, so nothing is fetched at all. The environment light is
model-viewer's built-in procedural ``neutral`` one.
"""

from __future__ import annotations

import base64
import html
import math
import shutil
import tempfile
from pathlib import Path
from typing import Callable

from pgc.errors import PGCDataError
from pgc.io.atomic import atomic_path, write_text

VIEWER_DIR = Path(__file__).resolve().parents[1] / "report_viewer"
"""The npm project of the viewer (``package.json``, ``package-lock.json``; setup installs ``node_modules``)."""
BUNDLE = Path("node_modules/@google/model-viewer/dist/model-viewer-umd.min.js")
"""The viewer as one classic script (a module script may not load from ``file://``): three.js and lit inside."""
BUNDLED = ("@google/model-viewer", "three", "lit", "lit-html", "lit-element", "@lit/reactive-element",
           "@monogrid/gainmap-js")
"""The npm packages whose code the bundle holds: their licence texts go beside it."""
BUNDLE_NAME = "model-viewer.min.js"
LICENCE_NAME = "model-viewer.LICENSE.txt"
MODEL_BUDGET = 4 * 2**20
"""Bytes (about) of the ``.glb`` the view embeds: above it, every k-th simulated frame becomes a morph target."""
SETUP_HINT = "run scripts/setup.sh (it installs @google/model-viewer with npm into pgc/report_viewer/node_modules)"


def viewer_bundle() -> Path | None:
    """The installed viewer bundle, or None when set-up has not installed it."""
    path = VIEWER_DIR / BUNDLE
    return path if path.is_file() else None


def licence_text() -> str:
    """The licences of every package in the bundle, each under its name, version and SPDX identifier."""
    import json

    parts = []
    for name in BUNDLED:
        folder = VIEWER_DIR / "node_modules" / name
        meta = json.loads((folder / "package.json").read_text())
        texts = [p.read_text() for p in sorted(folder.glob("LICEN[CS]E*")) if p.is_file()]
        if not texts:
            raise PGCDataError(f"{folder}: no licence file; reinstall the viewer ({SETUP_HINT})")
        parts.append(f"{'=' * 78}\n{name} {meta['version']} ({meta['license']})\n{'=' * 78}\n\n" + "\n".join(texts))
    return (f"{BUNDLE_NAME} is {BUNDLE.name} of @google/model-viewer, which bundles the packages below.\n\n"
            + "\n\n".join(parts))


def keyframe_stride(frames: int, base_bytes: int, frame_bytes: int, budget: int) -> int:
    """The smallest stride k such that frames 0, k, 2k, ... (each ``frame_bytes`` more than a one-frame file of
    ``base_bytes``) fit in ``budget`` bytes; at least 1, and at most what keeps two keyframes."""
    if frames <= 1:
        return 1
    keyframes = max(2, 1 + (budget - base_bytes) // max(frame_bytes, 1))
    return min(max(1, math.ceil((frames - 1) / (keyframes - 1))), frames - 1)


def _glb_bytes(asset, anim) -> bytes:
    from pgc.io.export import write_gltf

    with tempfile.TemporaryDirectory(prefix="pgc-report-glb-") as tmp:
        path = Path(tmp) / "model.glb"
        write_gltf(path, asset, anim)
        return path.read_bytes()


def run_glb(folder: Path, asset_dir: Path, run: dict) -> tuple[bytes, int, int]:
    """(the ``.glb`` of the run's garment and body, as ``pgc export --format gltf`` writes it, the stride
    between its keyframes, the simulated frames) within :data:`MODEL_BUDGET`."""
    import numpy as np

    from pgc.io.asset import read_asset
    from pgc.io.export import Animation

    asset = read_asset(asset_dir)
    with np.load(folder / "garment.npz") as g, np.load(folder / "body.npz") as b:
        garment, body, body_faces = g["vertices"], b["vertices"], b["faces"]
    if garment.ndim != 3 or garment.shape[1] != len(asset.garment.vertices) or len(body) != len(garment):
        raise PGCDataError(f"{folder / 'garment.npz'}: vertices {garment.shape} (body {body.shape}) do not fit the "
                           f"asset's garment ({len(asset.garment.vertices)} vertices); rerun 'pgc animate'")
    fps = float(run.get("fps", 30.0))
    one = len(_glb_bytes(asset, Animation(garment[:1], body[:1], body_faces, fps)))
    two = len(_glb_bytes(asset, Animation(garment[:2], body[:2], body_faces, fps))) if len(garment) > 1 else one
    k = keyframe_stride(len(garment), one, two - one, MODEL_BUDGET)
    return _glb_bytes(asset, Animation(garment[::k], body[::k], body_faces, fps / k)), k, len(garment)


PAGE_SCRIPT = """<script>
(function () {
  var status = document.getElementById('view3d-status');
  var viewer = document.getElementById('view3d');
  function say(state, text) { status.setAttribute('data-state', state); status.textContent = text; }
  viewer.addEventListener('load', function () {
    var names = viewer.availableAnimations || [];
    say('loaded', 'model loaded; animation' + (names.length ? ' "' + names.join('", "') + '" playing' : ': none'));
  });
  viewer.addEventListener('error', function (e) {
    say('error', 'the model did not load: ' + ((e.detail && e.detail.type) || 'error') + ' (WebGL off?)');
  });
  fetch('data:model/gltf-binary;base64,' + window.pgcModelBase64).then(function (r) { return r.blob(); })
    .then(function (blob) {
      var url = URL.createObjectURL(blob);
      document.getElementById('view3d-download').href = url;
      viewer.src = url;
    })
    .catch(function (e) { say('error', 'the embedded model could not be decoded: ' + e); });
})();
</script>"""
"""Decodes the embedded ``.glb`` (natively, through a data: URL) into a blob: URL for the viewer and the download
link, and reports the load in ``#view3d-status`` (``data-state``: loading, loaded, error)."""


def _offline(figures: str) -> str:
    """Read by each <model-viewer> when it is built: decoders from the report folder, never a CDN."""
    return (f"<script>self.ModelViewerElement = Object.assign(self.ModelViewerElement || {{}}, {{dracoDecoderLocation: "
            f"'{figures}/', ktx2TranscoderLocation: '{figures}/', lottieLoaderLocation: '{figures}/'}});</script>")


def view_section(folder: Path, asset_dir: Path, run: dict, motion: str, figures: str,
                 path: Callable[[str], Path]) -> str:
    """The 3D view of a run (its folder, its asset folder, its run.json) as HTML, its files written through
    ``path`` (name -> file in the report's ``figures`` folder); one line saying why and what to do when the
    viewer is not installed or the run cannot be exported."""
    head = "<section id='in-3d'><h2>In 3D</h2>"
    bundle = viewer_bundle()
    if bundle is None:
        return (f"{head}<p class='note'>No 3D view: the viewer is not installed; {html.escape(SETUP_HINT)}.</p>"
                "</section>")
    try:
        glb, k, frames = run_glb(folder, asset_dir, run)
    except (PGCDataError, OSError, KeyError, ModuleNotFoundError) as exc:
        export = f"pgc export {folder} --format gltf --out {motion}.glb"
        return (f"{head}<p class='note'>No 3D view of {html.escape(motion)}: {html.escape(str(exc))}. Once "
                f"<code>{html.escape(export)}</code> works, <code>pgc report</code> shows it.</p></section>")
    slug = motion.replace("/", "_")
    with atomic_path(path(BUNDLE_NAME)) as tmp:
        shutil.copyfile(bundle, tmp)
    write_text(path(LICENCE_NAME), licence_text())
    write_text(path(f"{slug}_3d.js"), f'window.pgcModelBase64 = "{base64.b64encode(glb).decode()}";\n')
    fps = float(run.get("fps", 30.0))
    used = len(range(0, frames, k))
    pace = "every simulated frame" if k == 1 else f"one in {k}, interpolated linearly between them"
    caption = (f"{html.escape(motion)}: the simulated garment on the body, {used} of {frames} frames at {fps:g} fps "
               f"({pace}), {(used - 1) * k / fps:.2f} s, looping. glTF 2.0 with morph targets and "
               f"KHR_materials_sheen, {len(glb) / 2**20:.2f} MiB, as <code>pgc export RUN --format gltf</code> "
               "writes it. Drag to turn, scroll to zoom.")
    return (f"{head}<script src='{figures}/{BUNDLE_NAME}'></script>{_offline(figures)}"
            "<figure class='view3d'><model-viewer id='view3d' camera-controls autoplay animation-name='motion' "
            "loading='eager' environment-image='neutral' interaction-prompt='none' "
            f"alt='{html.escape(motion)}: the simulated garment on the body'></model-viewer>"
            f"<figcaption>{caption} <a id='view3d-download' download='{html.escape(slug)}.glb'>download the "
            ".glb</a></figcaption></figure><p class='note' id='view3d-status' data-state='loading'>model not "
            f"loaded yet</p><script src='{figures}/{html.escape(slug)}_3d.js'></script>{PAGE_SCRIPT}</section>")
