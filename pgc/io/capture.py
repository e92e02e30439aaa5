"""Capture directories: ``transforms.json`` (nerfstudio / instant-ngp style) plus image files.

Layout written by :func:`write_capture` (``<name>`` is the camera name made file-safe)::

    transforms.json            frames, intrinsics, labels, light, metadata
    images/<name>.png|exr      colour (sRGB PNG 8/16-bit, or linear EXR)
    masks/<name>.png           foreground mask, grey PNG (8-bit; 16-bit with png16/exr)
    segmentation/<name>.png    garment segmentation, 8-bit label ids (see ``pgc_labels``)
    background/<name>.png|exr  the empty scene, same format as the images
    extras/<layer>/<name>.exr  ground-truth layers (e.g. albedo (H, W, 3) linear, depth (H, W) metres)
    light/envmap.exr           optional environment map

``transform_matrix`` is the OpenGL camera-to-world matrix (camera x right, y up, z backward), as in
nerfstudio and instant-ngp; PGC cameras are OpenCV world-to-camera (x right, y down, z forward). The
conversion happens here and only here. Intrinsics ``fl_x fl_y cx cy w h`` (pixels; pixel centres at
integer + 0.5, as in COLMAP and nerfstudio) are per frame, or top level as a default for all frames;
``camera_angle_x`` (NeRF synthetic) is accepted when ``fl_x`` is absent. Distortion ``k1 k2 p1 p2 [k3]``
(camera_model OPENCV) is written from :attr:`Camera.dist`; reading undistorts by default.

PGC keys (ignored by other tools): per frame ``pgc_name``, ``pgc_segmentation_path``,
``pgc_background_path``, ``pgc_extras`` ({layer: path}); top level ``pgc_labels`` ({id: name}),
``pgc_light`` ({radiance, rotation_deg, envmap_path}), ``pgc_metadata`` and ``pgc_version``.
"""

from __future__ import annotations

import math
import os
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import images as imgio
from pgc.io import limits
from pgc.io.atomic import ensure_folder, write_json
from pgc.types import DEFAULT_LABELS, Camera, Capture, Light, View

TRANSFORMS = "transforms.json"
FORMAT_VERSION = 1
IMAGE_FORMATS = ("png", "png16", "exr")
IO_THREADS = 4
"""Views read or written concurrently (PNG/EXR codecs and fsync release the GIL)."""

# OpenGL camera axes expressed in OpenCV camera axes (and back: the matrix is its own inverse).
_FLIP_YZ = np.diag([1.0, -1.0, -1.0])


def opengl_c2w_to_opencv_w2c(c2w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenGL camera-to-world (4, 4) or (3, 4) -> OpenCV world-to-camera ``(R (3, 3), t (3,))``."""
    c2w = np.asarray(c2w, dtype=np.float64)
    rot_cv = c2w[:3, :3] @ _FLIP_YZ  # columns: camera x, y (down), z (forward) in world coordinates
    R = rot_cv.T
    return R, -R @ c2w[:3, 3]


def opencv_w2c_to_opengl_c2w(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """OpenCV world-to-camera ``R, t`` -> OpenGL camera-to-world (4, 4)."""
    R = np.asarray(R, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = R.T @ _FLIP_YZ
    m[:3, 3] = -R.T @ np.asarray(t, dtype=np.float64)
    return m


def _safe_name(name: str, index: int, used: set[str]) -> str:
    base = re.sub(r"[^A-Za-z0-9_.-]", "_", name) or f"view{index:03d}"
    out, k = base, 1
    while out in used:
        out, k = f"{base}_{k}", k + 1
    used.add(out)
    return out


def _write_frame(root: Path, view: View, stem: str, ext: str, bits: int) -> dict[str, Any]:
    """Write the files of one view; returns its ``frames`` entry."""
    cam = view.camera
    K = cam.K
    if abs(K[0, 1]) > 1e-12 or not np.allclose(K[2], [0.0, 0.0, 1.0]):
        raise ValueError(f"camera '{cam.name}': transforms.json cannot hold skew or a non-standard K "
                         f"last row, K = {K.tolist()}")
    frame: dict[str, Any] = {
        "file_path": f"images/{stem}{ext}",
        "transform_matrix": opencv_w2c_to_opengl_c2w(cam.R, cam.t).tolist(),
        "fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
        "w": cam.width, "h": cam.height,
        "pgc_name": cam.name,
    }
    if cam.dist is not None:
        frame.update(_dist_to_keys(cam.dist, cam.name))
    imgio.write_image(root / frame["file_path"], view.image, bits=bits)
    if view.mask is not None:
        frame["mask_path"] = f"masks/{stem}.png"
        imgio.write_mask(root / frame["mask_path"], view.mask, bits=bits)
    if view.segmentation is not None:
        frame["pgc_segmentation_path"] = f"segmentation/{stem}.png"
        imgio.write_labels(root / frame["pgc_segmentation_path"], view.segmentation)
    if view.background is not None:
        frame["pgc_background_path"] = f"background/{stem}{ext}"
        imgio.write_image(root / frame["pgc_background_path"], view.background, bits=bits)
    if view.extras:
        frame["pgc_extras"] = {}
        for layer, array in view.extras.items():
            if not re.fullmatch(r"[A-Za-z0-9_.-]+", layer):
                raise ValueError(f"extra layer name '{layer}' must be file-safe ([A-Za-z0-9_.-])")
            rel = f"extras/{layer}/{stem}.exr"
            imgio.write_exr(root / rel, array)
            frame["pgc_extras"][layer] = rel
    return frame


def write_capture(root: str | os.PathLike, capture: Capture, image_format: str = "png") -> None:
    """Write ``capture`` as a capture directory (see the module docstring for the layout).

    ``image_format``: 'png' (8-bit sRGB), 'png16' (16-bit sRGB) or 'exr' (linear float32) for the colour
    images and backgrounds; masks are 8-bit PNG for 'png', 16-bit otherwise. Every file is written
    atomically and ``transforms.json`` last, so a reader never sees a half-written capture.
    """
    if image_format not in IMAGE_FORMATS:
        raise ValueError(f"image_format must be one of {IMAGE_FORMATS}, got '{image_format}'")
    root = ensure_folder(root)
    ext = ".exr" if image_format == "exr" else ".png"
    bits = 8 if image_format == "png" else 16
    used: set[str] = set()
    stems = [_safe_name(v.camera.name, i, used) for i, v in enumerate(capture.views)]
    with ThreadPoolExecutor(max_workers=IO_THREADS) as pool:  # codecs and fsync release the GIL
        frames = list(pool.map(lambda vs: _write_frame(root, *vs, ext, bits), zip(capture.views, stems)))
    doc: dict[str, Any] = {"camera_model": "OPENCV" if any("k1" in f for f in frames) else "PINHOLE",
                           "pgc_version": FORMAT_VERSION,
                           "pgc_labels": {str(k): v for k, v in sorted(capture.labels.items())}}
    if capture.light is not None:
        light = capture.light
        doc["pgc_light"] = {"radiance": light.radiance.tolist(), "rotation_deg": float(light.rotation_deg)}
        if light.envmap is not None:
            doc["pgc_light"]["envmap_path"] = "light/envmap.exr"
            imgio.write_exr(root / "light/envmap.exr", light.envmap)
    doc["pgc_metadata"] = capture.metadata
    doc["frames"] = frames
    write_json(root / TRANSFORMS, doc)


def _dist_to_keys(dist: np.ndarray, name: str) -> dict[str, float]:
    d = np.asarray(dist, dtype=np.float64).ravel()
    if d.size not in (4, 5):
        raise ValueError(f"camera '{name}': distortion must be (k1, k2, p1, p2[, k3]), got {d.size} values")
    return dict(zip(("k1", "k2", "p1", "p2", "k3"), map(float, d)))


# ------------------------------------------------------------------------------------------- reading

class _Doc:
    """Field access on transforms.json that names the file, the frame and the key in every error."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, where: str, problem: str) -> PGCDataError:
        return PGCDataError(f"{self.path}: {where}: {problem}")

    def pixels(self, obj: dict, key: str, where: str, default: int | None = None) -> int | None:
        """An image size in pixels: a positive whole number (``64.0`` is 64; ``64.7`` is refused)."""
        value = self.number(obj, key, where)
        if value is None:
            return default
        if value != int(value) or not 0 < value <= limits.MAX_IMAGE_PIXELS:
            raise self.fail(where, f"'{key}' must be a whole number of pixels in [1, {limits.MAX_IMAGE_PIXELS}], "
                                   f"got {obj[key]!r}")
        return int(value)

    def number(self, obj: dict, key: str, where: str, default: float | None = None) -> float | None:
        if key not in obj:
            return default
        value = obj[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(where, f"'{key}' must be a finite number, got {value!r}")
        return float(value)


def read_capture(root: str | os.PathLike, undistort: bool = True, check: bool = True) -> Capture:
    """Read a capture directory (or a ``transforms.json`` path) into a :class:`Capture`.

    Frames with distortion (``k1 k2 p1 p2 [k3]``) are resampled to the pinhole camera with the same ``K``
    (OpenCV; segmentation nearest, other layers bilinear) unless ``undistort`` is False, in which case the
    coefficients stay in :attr:`Camera.dist`.

    Raises :class:`PGCDataError` naming the file and the problem on malformed JSON, missing or
    unreadable files, non-finite or non-rigid matrices, images whose size disagrees with the intrinsics,
    and optional layers present for some frames only; and sizes above :mod:`pgc.io.limits`. With ``check``
    (the default) it also refuses a capture nothing can be reconstructed from
    (:func:`pgc.io.capture_checks.check_capture`: no baseline, masks all full or all empty).
    """
    root = Path(root)
    path = root if root.suffix == ".json" else root / TRANSFORMS
    root = path.parent
    if not path.is_file():
        raise PGCDataError(f"{path}: not found; a capture directory needs a {TRANSFORMS}")
    doc = limits.read_json(path, f"capture's {TRANSFORMS}")
    d = _Doc(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("frames"), list) or not doc["frames"]:
        raise d.fail("top level", "needs a non-empty list 'frames'")
    version = doc.get("pgc_version", FORMAT_VERSION)
    if version != FORMAT_VERSION:
        raise d.fail("pgc_version", f"unsupported capture format version {version!r} (this PGC reads "
                                    f"{FORMAT_VERSION}); upgrade PGC")
    frames = doc["frames"]
    limits.check_count(path, "frames", len(frames), limits.MAX_VIEWS, "frames")
    _check_layer_counts(d, frames)
    labels = _read_labels(d, doc)
    light = _read_light(d, root, doc.get("pgc_light"))
    metadata = doc.get("pgc_metadata", {})
    if not isinstance(metadata, dict):
        raise d.fail("pgc_metadata", "must be an object")
    with ThreadPoolExecutor(max_workers=IO_THREADS) as pool:  # the first failing frame (in order) raises
        sizes = list(pool.map(lambda i: _frame_size(d, root, frames[i], i), range(len(frames))))
        total = sum(w * h for _, (w, h) in sizes)
        if total > limits.MAX_CAPTURE_PIXELS:
            raise d.fail("frames", f"the {len(frames)} images hold {total} pixels together, more than the limit of "
                                   f"{limits.MAX_CAPTURE_PIXELS} (pgc.io.limits.MAX_CAPTURE_PIXELS); use fewer or "
                                   "smaller images")
        views = list(pool.map(lambda i: _read_frame(d, root, doc, frames[i], i, undistort, *sizes[i]),
                              range(len(frames))))
    names = [v.camera.name for v in views]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise d.fail("frames", f"camera names must be unique; repeated: {dup}")
    capture = Capture(views=views, labels=labels, light=light, metadata=metadata, root=str(root))
    if check:
        from pgc.io.capture_checks import check_capture

        check_capture(capture, str(path))
    return capture


def _check_layer_counts(d: _Doc, frames: list) -> None:
    for i, f in enumerate(frames):
        if not isinstance(f, dict):
            raise d.fail(f"frames[{i}]", "must be an object")
    for key in ("mask_path", "pgc_segmentation_path", "pgc_background_path"):
        have = [i for i, f in enumerate(frames) if key in f]
        if have and len(have) != len(frames):
            missing = [i for i in range(len(frames)) if key not in frames[i]]
            raise d.fail(key, f"given for {len(have)} of {len(frames)} frames (missing in frames {missing[:8]}); "
                              "give it for every frame or for none")
    for i, f in enumerate(frames):
        if not isinstance(f.get("pgc_extras", {}), dict):
            raise d.fail(f"frames[{i}].pgc_extras", "must be an object {layer: path}")
    layers = [tuple(sorted(f.get("pgc_extras", {}))) for f in frames]
    if len(set(layers)) > 1:
        raise d.fail("pgc_extras", f"frames list different ground-truth layers: {sorted(set(layers))}; "
                                   "every frame must have the same layers")


def _resolve(d: _Doc, root: Path, rel: Any, where: str) -> Path:
    if not isinstance(rel, str) or not rel:
        raise d.fail(where, f"path must be a non-empty string, got {rel!r}")
    if os.path.isabs(rel) or ".." in re.split(r"[/\\]", rel):
        raise d.fail(where, f"{rel!r} is not a relative path inside the capture folder {root}; a capture is "
                            "self-contained (its folder is what is hashed): copy the file into it")
    p = root / rel
    if not p.suffix and not p.exists():  # NeRF synthetic writes "./train/r_0" without extension
        p = p.with_suffix(".png")
    if not p.is_file():
        raise d.fail(where, f"file not found: {p}")
    return p


def _frame_size(d: _Doc, root: Path, frame: dict, i: int) -> tuple[Path, tuple[int, int]]:
    """A frame's image file and its (width, height) from the file's header (nothing decoded)."""
    img_path = _resolve(d, root, frame.get("file_path"), f"frames[{i}].file_path")
    return img_path, imgio.image_size(img_path)


def _read_frame(d: _Doc, root: Path, doc: dict, frame: dict, i: int, undistort: bool, img_path: Path,
                size: tuple[int, int]) -> View:
    where = f"frames[{i}]"
    width, height = size
    w = d.pixels(frame, "w", where, d.pixels(doc, "w", "top level"))
    h = d.pixels(frame, "h", where, d.pixels(doc, "h", "top level"))
    if (w is not None and w != width) or (h is not None and h != height):
        raise d.fail(where, f"image {img_path.name} is {width}x{height} but the intrinsics say w={w} h={h}")
    K = _intrinsics(d, doc, frame, where, width, height)
    R, t = _extrinsics(d, frame, where)
    dist = _distortion(d, doc, frame, where)
    name = frame.get("pgc_name", img_path.stem)
    if not isinstance(name, str):
        raise d.fail(where, f"'pgc_name' must be a string, got {name!r}")
    camera = Camera(K=K, R=R, t=t, width=width, height=height, name=name, dist=dist)
    image = imgio.read_image(img_path)
    layers: dict[str, Any] = {}
    for key, reader, field in (("mask_path", imgio.read_mask, "mask"),
                               ("pgc_segmentation_path", imgio.read_labels, "segmentation"),
                               ("pgc_background_path", imgio.read_image, "background")):
        if key in frame:
            layers[field] = _read_layer(d, root, frame[key], f"{where}.{key}", reader, (height, width))
    extras = frame.get("pgc_extras", {})
    if not isinstance(extras, dict):
        raise d.fail(f"{where}.pgc_extras", "must be an object {layer: path}")
    layers["extras"] = {k: _read_layer(d, root, v, f"{where}.pgc_extras.{k}", imgio.read_exr, (height, width))
                        for k, v in extras.items()}
    if undistort and dist is not None:
        image = imgio.undistort(image, K, dist)
        for field in ("mask", "segmentation", "background"):
            if field in layers:
                layers[field] = imgio.undistort(layers[field], K, dist,
                                                "nearest" if field == "segmentation" else "linear")
        layers["extras"] = {k: imgio.undistort(v, K, dist) for k, v in layers["extras"].items()}
        camera = replace(camera, dist=None)
    try:
        return View(camera=camera, image=image, **layers)
    except PGCDataError as exc:
        raise d.fail(where, str(exc)) from exc


def _read_layer(d: _Doc, root: Path, rel: Any, where: str, reader, hw: tuple[int, int]) -> np.ndarray:
    p = _resolve(d, root, rel, where)
    try:
        a = reader(p)
    except PGCDataError as exc:
        raise d.fail(where, str(exc)) from exc
    if a.shape[:2] != hw:
        raise d.fail(where, f"{p.name} is {a.shape[1]}x{a.shape[0]} but the image is {hw[1]}x{hw[0]}")
    if not np.all(np.isfinite(a)):
        raise d.fail(where, f"{p.name} holds non-finite values (NaN or Inf)")
    return a


def _intrinsics(d: _Doc, doc: dict, frame: dict, where: str, width: int, height: int) -> np.ndarray:
    def get(key: str) -> float | None:
        return d.number(frame, key, where, d.number(doc, key, "top level"))

    fx, fy = get("fl_x"), get("fl_y")
    if fx is None:
        angle = get("camera_angle_x")
        if angle is None:
            raise d.fail(where, "no focal length: give 'fl_x' (and 'fl_y') per frame or at the top level")
        fx = 0.5 * width / math.tan(0.5 * angle)
    if fy is None:
        angle_y = get("camera_angle_y")
        fy = fx if angle_y is None else 0.5 * height / math.tan(0.5 * angle_y)
    if fx <= 0 or fy <= 0:
        raise d.fail(where, f"focal lengths must be positive, got fl_x={fx} fl_y={fy}")
    cx, cy = get("cx"), get("cy")
    return np.array([[fx, 0.0, width / 2 if cx is None else cx],
                     [0.0, fy, height / 2 if cy is None else cy],
                     [0.0, 0.0, 1.0]])


def _extrinsics(d: _Doc, frame: dict, where: str) -> tuple[np.ndarray, np.ndarray]:
    raw = frame.get("transform_matrix")
    try:
        m = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        m = np.zeros(0)
    if m.shape not in ((4, 4), (3, 4)):
        raise d.fail(where, f"'transform_matrix' must be a 4x4 (or 3x4) list of numbers, got {raw!r:.80}")
    if not np.all(np.isfinite(m)):
        raise d.fail(where, "'transform_matrix' holds NaN or Inf")
    if m.shape == (4, 4) and not np.allclose(m[3], [0, 0, 0, 1], atol=1e-6):
        raise d.fail(where, f"'transform_matrix' last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    rot = m[:3, :3]
    err = np.abs(rot.T @ rot - np.eye(3)).max()
    if err > 1e-4 or np.linalg.det(rot) < 0:
        raise d.fail(where, "'transform_matrix' rotation is not orthonormal with det +1 "
                            f"(max |R^T R - I| = {err:.2e}); scaled or mirrored cameras are not supported")
    return opengl_c2w_to_opencv_w2c(m)


def _distortion(d: _Doc, doc: dict, frame: dict, where: str) -> np.ndarray | None:
    vals = [d.number(frame, k, where, d.number(doc, k, "top level")) for k in ("k1", "k2", "p1", "p2", "k3")]
    if all(v is None or v == 0.0 for v in vals):
        return None
    coeffs = [0.0 if v is None else v for v in vals]
    return np.array(coeffs[:4] if vals[4] is None else coeffs)


def _read_labels(d: _Doc, doc: dict) -> dict[int, str]:
    raw = doc.get("pgc_labels")
    if raw is None:
        return dict(DEFAULT_LABELS)
    if not isinstance(raw, dict):
        raise d.fail("pgc_labels", "must be an object {id: name}")
    labels = {}
    for k, v in raw.items():
        if not (isinstance(k, str) and k.isdigit() and 0 <= int(k) <= 255 and isinstance(v, str)):
            raise d.fail("pgc_labels", f"entry {k!r}: {v!r} must map an id 0..255 to a name")
        labels[int(k)] = v
    return labels


def _read_light(d: _Doc, root: Path, raw: Any) -> Light | None:
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise d.fail("pgc_light", "must be an object {radiance, rotation_deg, envmap_path}")
    try:
        radiance = np.asarray(raw.get("radiance", [1.0, 1.0, 1.0]), dtype=np.float64)
    except (TypeError, ValueError):
        radiance = np.zeros(0)
    if radiance.shape != (3,) or not np.all(np.isfinite(radiance)):
        raise d.fail("pgc_light.radiance", f"must be 3 finite numbers, got {raw.get('radiance')!r}")
    rotation = d.number(raw, "rotation_deg", "pgc_light", 0.0)
    envmap = None
    if "envmap_path" in raw:
        envmap = imgio.read_envmap(_resolve(d, root, raw["envmap_path"], "pgc_light.envmap_path"))
    return Light(radiance=radiance, envmap=envmap, rotation_deg=rotation)
