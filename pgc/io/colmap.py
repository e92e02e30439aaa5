"""COLMAP sparse models (text and binary) -> cameras, images, points, and a :class:`Capture`.

COLMAP stores world-to-camera poses in the OpenCV convention (quaternion ``qw qx qy qz`` and ``t``) and
puts pixel centres at integer + 0.5, as PGC does, so poses and intrinsics carry over unchanged.
Supported camera models: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV. Images of distorted
models are undistorted with OpenCV (``pip install 'pgc[opencv]'``) into a pinhole camera with the same
``K``; without OpenCV that is a clear error.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.types import Camera, Capture, View

# model id -> (name, number of parameters); every COLMAP model, so any binary file parses
CAMERA_MODELS: dict[int, tuple[str, int]] = {
    0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4), 3: ("RADIAL", 5), 4: ("OPENCV", 8),
    5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12), 7: ("FOV", 5), 8: ("SIMPLE_RADIAL_FISHEYE", 4),
    9: ("RADIAL_FISHEYE", 5), 10: ("THIN_PRISM_FISHEYE", 12), 11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16),
}
MODEL_IDS = {name: (i, n) for i, (name, n) in CAMERA_MODELS.items()}
SUPPORTED = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")
FOCAL_XY = ("PINHOLE", "OPENCV", "OPENCV_FISHEYE", "FULL_OPENCV", "FOV", "THIN_PRISM_FISHEYE",
            "RAD_TAN_THIN_PRISM_FISHEYE")
"""Models whose first two parameters are the focal lengths fx, fy (the others start with one focal length f)."""
QUATERNION_TOLERANCE = 1e-3
"""Largest accepted difference between a pose quaternion's norm and 1."""


@dataclass
class ColmapCamera:
    id: int
    model: str
    width: int
    height: int
    params: np.ndarray

    def intrinsics(self, where: str) -> tuple[np.ndarray, np.ndarray | None]:
        """``K`` (3, 3) and OpenCV distortion (k1, k2, p1, p2) or None; unsupported models fail."""
        p = self.params
        if self.model == "SIMPLE_PINHOLE":
            f, cx, cy, dist = p[0], p[1], p[2], None
            fx = fy = f
        elif self.model == "PINHOLE":
            fx, fy, cx, cy, dist = p[0], p[1], p[2], p[3], None
        elif self.model == "SIMPLE_RADIAL":
            fx = fy = p[0]
            cx, cy, dist = p[1], p[2], np.array([p[3], 0.0, 0.0, 0.0])
        elif self.model == "RADIAL":
            fx = fy = p[0]
            cx, cy, dist = p[1], p[2], np.array([p[3], p[4], 0.0, 0.0])
        elif self.model == "OPENCV":
            fx, fy, cx, cy = p[:4]
            dist = np.array(p[4:8])
        else:
            raise PGCDataError(f"{where}: camera {self.id} uses the COLMAP model {self.model}; supported: "
                               f"{', '.join(SUPPORTED)} (undistort with 'colmap image_undistorter' first)")
        if dist is not None and not np.any(dist):
            dist = None
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return K, dist


@dataclass
class ColmapImage:
    id: int
    qvec: np.ndarray
    """(4,) world-to-camera rotation (w, x, y, z)."""
    tvec: np.ndarray
    """(3,) world-to-camera translation."""
    camera_id: int
    name: str
    xys: np.ndarray
    """(P, 2) keypoint positions (pixels)."""
    point3d_ids: np.ndarray
    """(P,) ids into the points, -1 where none."""

    def rotation(self) -> np.ndarray:
        w, x, y, z = self.qvec / np.linalg.norm(self.qvec)
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@dataclass
class ColmapPoints:
    ids: np.ndarray
    """(N,) int64 point ids."""
    xyz: np.ndarray
    """(N, 3) float64 world positions."""
    rgb: np.ndarray
    """(N, 3) uint8 sRGB colours."""
    error: np.ndarray
    """(N,) float64 mean reprojection error (pixels)."""


class _Reader:
    """Sequential little-endian reads that name the file when it ends early, and that refuse counts larger
    than what is left of the file before allocating anything."""

    def __init__(self, f: BinaryIO, path: Path):
        self.f, self.path = f, path
        self.size = limits.check_file_size(path, limits.MAX_TEXT_BYTES, "COLMAP model file")

    def count(self, what: str, record_bytes: int) -> int:
        """A record count (uint64), checked against the limits and the bytes left in the file."""
        (n,) = self.read("Q")
        limits.check_count(self.path, what, n, limits.MAX_ELEMENTS)
        if n * record_bytes > self.size - self.f.tell():
            raise PGCDataError(f"{self.path}: truncated binary file: {what} says {n} records of at least "
                               f"{record_bytes} bytes, but {self.size - self.f.tell()} bytes are left")
        return n

    def read(self, fmt: str):
        size = struct.calcsize("<" + fmt)
        data = self.f.read(size)
        if len(data) != size:
            raise PGCDataError(f"{self.path}: truncated binary file (ended inside a record)")
        return struct.unpack("<" + fmt, data)

    def array(self, dtype: str, count: int) -> np.ndarray:
        dt = np.dtype(dtype)
        if dt.itemsize * count > self.size - self.f.tell():
            raise PGCDataError(f"{self.path}: truncated binary file (a record of {count} entries ends past the "
                               "end of the file)")
        data = self.f.read(dt.itemsize * count)
        if len(data) != dt.itemsize * count:
            raise PGCDataError(f"{self.path}: truncated binary file (ended inside a record)")
        return np.frombuffer(data, dtype=dt, count=count)

    def string(self) -> str:
        out = bytearray()
        while (c := self.f.read(1)) not in (b"\x00", b""):
            out += c
        if c == b"":
            raise PGCDataError(f"{self.path}: truncated binary file (unterminated image name)")
        try:
            return out.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise PGCDataError(f"{self.path}: image name {bytes(out)!r} is not UTF-8 ({exc.reason}); rename the "
                               "image") from None


def _read_cameras_bin(path: Path) -> dict[int, ColmapCamera]:
    cams = {}
    with open(path, "rb") as f:
        r = _Reader(f, path)
        for _ in range(r.count("number of cameras", 24)):
            cam_id, model_id, width, height = r.read("iiQQ")
            if model_id not in CAMERA_MODELS:
                raise PGCDataError(f"{path}: camera {cam_id} has unknown model id {model_id}")
            name, n_params = CAMERA_MODELS[model_id]
            cam = ColmapCamera(cam_id, name, width, height, np.array(r.read(f"{n_params}d")))
            _add_unique(cams, cam_id, _checked_camera(cam, f"{path}: camera {cam_id}"), path, "camera")
    return cams


def _read_images_bin(path: Path) -> dict[int, ColmapImage]:
    images = {}
    with open(path, "rb") as f:
        r = _Reader(f, path)
        for _ in range(r.count("number of images", 73)):
            image_id, *rest = r.read("i7di")
            qvec, tvec, cam_id = np.array(rest[0:4]), np.array(rest[4:7]), rest[7]
            name = r.string()
            n_pts = r.count(f"number of keypoints of image {image_id}", 24)
            pts = r.array("<f8,<f8,<i8", n_pts)
            xys = np.stack([pts["f0"], pts["f1"]], axis=1) if n_pts else np.zeros((0, 2))
            _add_unique(images, image_id, ColmapImage(image_id, qvec, tvec, cam_id, name, xys,
                                                      pts["f2"].astype(np.int64)), path, "image")
    return images


def _read_points_bin(path: Path) -> ColmapPoints:
    ids, xyz, rgb, err = [], [], [], []
    with open(path, "rb") as f:
        r = _Reader(f, path)
        for _ in range(r.count("number of points", 51)):
            pid, x, y, z, cr, cg, cb, e, track_len = r.read("Q3d3BdQ")
            limits.check_count(path, f"track length of point {pid}", track_len, limits.MAX_ELEMENTS)
            r.array("<i4", 2 * track_len)
            ids.append(pid), xyz.append((x, y, z)), rgb.append((cr, cg, cb)), err.append(e)
    return ColmapPoints(np.array(ids, np.int64), np.array(xyz, np.float64).reshape(-1, 3),
                        np.array(rgb, np.uint8).reshape(-1, 3), np.array(err, np.float64))


def _read_text(path: Path) -> list[str]:
    """The lines of a COLMAP text file (UTF-8, at most :data:`pgc.io.limits.MAX_TEXT_BYTES`)."""
    limits.check_file_size(path, limits.MAX_TEXT_BYTES, "COLMAP model file")
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8").splitlines()
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise PGCDataError(f"{path}:{line}: not UTF-8 text (byte {exc.start}: {exc.reason}); COLMAP writes UTF-8: "
                           "re-export the model or fix the file's encoding") from None


def _text_lines(path: Path):
    for lineno, line in enumerate(_read_text(path), 1):
        line = line.strip()
        if line and not line.startswith("#"):
            yield lineno, line


def _add_unique(table: dict, key: int, value, path: Path, what: str, where: str = "") -> None:
    if key in table:
        raise PGCDataError(f"{where or path}: {what} id {key} appears twice; every {what} needs its own id")
    table[key] = value


def _checked_camera(cam: ColmapCamera, where: str) -> ColmapCamera:
    """Refuse a camera with a non-positive or huge size, non-finite parameters or a non-positive focal length."""
    if not (0 < cam.width and 0 < cam.height and cam.width * cam.height <= limits.MAX_IMAGE_PIXELS):
        raise PGCDataError(f"{where}: image size {cam.width}x{cam.height} must be positive and at most "
                           f"{limits.MAX_IMAGE_PIXELS} pixels; fix WIDTH HEIGHT")
    if not np.all(np.isfinite(cam.params)):
        raise PGCDataError(f"{where}: parameters {cam.params.tolist()} must be finite numbers; fix PARAMS")
    focal = cam.params[:2] if cam.model in FOCAL_XY else cam.params[:1]
    if np.any(focal <= 0):
        raise PGCDataError(f"{where}: focal length {focal.tolist()} must be positive (model {cam.model}); fix the "
                           "first parameter(s)")
    return cam


def _read_cameras_txt(path: Path) -> dict[int, ColmapCamera]:
    cams = {}
    for lineno, line in _text_lines(path):
        parts = line.split()
        try:
            cam_id, model, width, height = int(parts[0]), parts[1], int(parts[2]), int(parts[3])
            params = np.array([float(x) for x in parts[4:]])
        except (IndexError, ValueError):
            raise PGCDataError(f"{path}:{lineno}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS...'") from None
        if model not in MODEL_IDS:
            raise PGCDataError(f"{path}:{lineno}: unknown camera model '{model}'")
        if len(params) != MODEL_IDS[model][1]:
            raise PGCDataError(f"{path}:{lineno}: {model} takes {MODEL_IDS[model][1]} parameters, got {len(params)}")
        where = f"{path}:{lineno}"
        _add_unique(cams, cam_id, _checked_camera(ColmapCamera(cam_id, model, width, height, params),
                                                  f"{where}: camera {cam_id}"), path, "camera", where)
    return cams


def _read_images_txt(path: Path) -> dict[int, ColmapImage]:
    """Two lines per image: the pose line and the keypoint line (which may be empty)."""
    images: dict[int, ColmapImage] = {}
    raw = [(n, ln.strip()) for n, ln in enumerate(_read_text(path), 1) if not ln.startswith("#")]
    i = 0
    while i < len(raw):
        lineno, line = raw[i]
        if not line:  # blank line between records or at the end
            i += 1
            continue
        head = line.split()
        try:
            image_id = int(head[0])
            q = np.array([float(x) for x in head[1:5]])
            t = np.array([float(x) for x in head[5:8]])
            cam_id, name = int(head[8]), " ".join(head[9:])
        except (IndexError, ValueError):
            raise PGCDataError(f"{path}:{lineno}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME'") from None
        if len(q) != 4 or len(t) != 3 or not name:
            raise PGCDataError(f"{path}:{lineno}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME'")
        pts = raw[i + 1][1].split() if i + 1 < len(raw) else []
        if len(pts) % 3:
            raise PGCDataError(f"{path}:{lineno + 1}: keypoints of image {image_id} are not (X, Y, POINT3D_ID) "
                               "triples")
        try:
            arr = np.array(pts, dtype=np.float64).reshape(-1, 3)
        except ValueError:
            raise PGCDataError(f"{path}:{lineno + 1}: keypoints of image {image_id} must be numbers") from None
        _add_unique(images, image_id, ColmapImage(image_id, q, t, cam_id, name, arr[:, :2],
                                                  arr[:, 2].astype(np.int64)), path, "image", f"{path}:{lineno}")
        i += 2
    return images


def _read_points_txt(path: Path) -> ColmapPoints:
    rows = []
    for lineno, line in _text_lines(path):
        parts = line.split()
        try:
            rows.append([float(x) for x in parts[:8]])
        except ValueError:
            raise PGCDataError(f"{path}:{lineno}: expected 'POINT3D_ID X Y Z R G B ERROR TRACK...'") from None
        if len(rows[-1]) != 8:
            raise PGCDataError(f"{path}:{lineno}: expected 'POINT3D_ID X Y Z R G B ERROR TRACK...'")
    a = np.array(rows, dtype=np.float64).reshape(-1, 8)
    return ColmapPoints(a[:, 0].astype(np.int64), a[:, 1:4], a[:, 4:7].astype(np.uint8), a[:, 7])


def read_colmap_model(sparse_dir: str | os.PathLike) -> tuple[dict[int, ColmapCamera], dict[int, ColmapImage],
                                                              ColmapPoints]:
    """Read ``cameras``, ``images`` and ``points3D`` (``.bin`` preferred over ``.txt``) of a sparse model.

    ``points3D`` is optional (empty points when absent). Images that reference a missing camera fail.
    """
    sparse_dir = Path(sparse_dir)
    readers = {"cameras": (_read_cameras_bin, _read_cameras_txt), "images": (_read_images_bin, _read_images_txt),
               "points3D": (_read_points_bin, _read_points_txt)}
    out = {}
    for stem, (read_bin, read_txt) in readers.items():
        if (sparse_dir / f"{stem}.bin").is_file():
            out[stem] = read_bin(sparse_dir / f"{stem}.bin")
        elif (sparse_dir / f"{stem}.txt").is_file():
            out[stem] = read_txt(sparse_dir / f"{stem}.txt")
        elif stem == "points3D":
            out[stem] = ColmapPoints(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3), np.uint8), np.zeros(0))
        else:
            raise PGCDataError(f"{sparse_dir}: no {stem}.bin or {stem}.txt; is this a COLMAP sparse model folder "
                               "(e.g. sparse/0)?")
    cameras, images = out["cameras"], out["images"]
    images_file = next(sparse_dir / f"images.{e}" for e in ("bin", "txt") if (sparse_dir / f"images.{e}").is_file())
    for img in images.values():
        norm = float(np.linalg.norm(img.qvec))
        if not (np.all(np.isfinite(img.qvec)) and norm > 1e-8):
            raise PGCDataError(f"{images_file}: image {img.id} ('{img.name}') has the quaternion "
                               f"{img.qvec.tolist()}, which is no rotation (zero or non-finite); fix QW QX QY QZ")
        if abs(norm - 1.0) > QUATERNION_TOLERANCE:
            raise PGCDataError(f"{images_file}: image {img.id} ('{img.name}') has the quaternion "
                               f"{img.qvec.tolist()} of norm {norm:.6g}, not a unit quaternion (COLMAP writes unit "
                               "quaternions; is the line corrupt or are the columns out of order?); fix QW QX QY QZ")
        parts = Path(img.name).parts
        if not parts or Path(img.name).is_absolute() or ".." in parts:
            raise PGCDataError(f"{images_file}: image {img.id} has the name {img.name!r}, which is not a path "
                               "inside the image folder (absolute or with '..'); fix NAME")
        if not np.all(np.isfinite(img.tvec)):
            raise PGCDataError(f"{images_file}: image {img.id} ('{img.name}') has a non-finite translation "
                               f"{img.tvec.tolist()}; fix TX TY TZ")
        if img.camera_id not in cameras:
            raise PGCDataError(f"{sparse_dir}: image {img.id} ('{img.name}') references camera {img.camera_id}, "
                               f"but the model has {len(cameras)} camera(s) with ids {sorted(cameras)}")
    if not images:
        raise PGCDataError(f"{sparse_dir}: the model has no registered images")
    return cameras, images, out["points3D"]


def capture_from_colmap(sparse_dir: str | os.PathLike, image_dir: str | os.PathLike,
                        mask_dir: str | os.PathLike | None = None) -> Capture:
    """A :class:`Capture` of every registered image of a COLMAP model (sorted by image name).

    Images are read from ``image_dir/NAME``; masks, when ``mask_dir`` is given, from ``mask_dir/NAME.png``
    (COLMAP's mask naming). Distorted cameras are undistorted (images bilinear, masks nearest).
    ``metadata['colmap']`` records the folder and the number of 3D points.
    """
    from pgc.io.images import image_size, read_image, read_mask, undistort

    sparse_dir, image_dir = Path(sparse_dir), Path(image_dir)
    cameras, images, points = read_colmap_model(sparse_dir)
    stems = [Path(i.name).stem for i in images.values()]
    unique_stems = len(set(stems)) == len(stems)
    views = []
    for img in sorted(images.values(), key=lambda i: i.name):
        cam = cameras[img.camera_id]
        K, dist = cam.intrinsics(str(sparse_dir))
        path = image_dir / img.name
        if not path.is_file():
            raise PGCDataError(f"{path}: image '{img.name}' of the COLMAP model not found in {image_dir}")
        if image_size(path) != (cam.width, cam.height):
            w, h = image_size(path)
            raise PGCDataError(f"{path}: image is {w}x{h} but COLMAP camera {cam.id} is {cam.width}x{cam.height}")
        image = read_image(path)
        mask = read_mask(Path(mask_dir) / f"{img.name}.png") if mask_dir is not None else None
        if mask is not None and mask.shape != image.shape[:2]:
            raise PGCDataError(f"{Path(mask_dir) / (img.name + '.png')}: mask size {mask.shape[::-1]} != image size "
                               f"{image.shape[1::-1]}")
        if dist is not None:
            image = undistort(image, K, dist)
            mask = None if mask is None else undistort(mask, K, dist, interpolation="nearest")
        camera = Camera(K=K, R=img.rotation(), t=img.tvec, width=cam.width, height=cam.height,
                        name=Path(img.name).stem if unique_stems else img.name)
        views.append(View(camera=camera, image=image, mask=mask))
    return Capture(views=views, metadata={"colmap": {"sparse_dir": str(sparse_dir), "num_points": len(points.ids)}})
