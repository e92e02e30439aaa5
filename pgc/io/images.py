"""Image files: PNG (8/16-bit, sRGB-encoded colour), EXR (linear float), grey masks and label maps.

Inside PGC colour is float32 *linear* RGB; PNG colour files hold sRGB code values and are converted
with the exact IEC 61966-2-1 transfer functions. Masks are stored as plain grey code values
(value / (2^bits - 1)), label maps as 8-bit ids, EXR as float32 channels (R, G, B[, A] or Y).
Every reader raises :class:`PGCDataError` naming the file on a bad or missing file.
Writes are atomic (see :mod:`pgc.io.atomic`).
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any

import numpy as np

from pgc.arrays import float_operands
from pgc.errors import PGCDataError, PGCPluginError
from pgc.io import limits
from pgc.io.atomic import atomic_path

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
EXR_SUFFIXES = (".exr",)
PNG_SUFFIXES = (".png",)


def srgb_to_linear(x: Any) -> Any:
    """sRGB-encoded values (clipped to [0, 1]) -> linear (the exact piecewise transfer function).

    Written once over :mod:`pgc.arrays`: torch and JAX arrays keep their dtype (differentiable, finite
    gradients); anything else is computed in float64 and returned as float32 numpy (PGC's image values)."""
    ops, x = float_operands(x)
    x = ops.clip(x, 0.0, 1.0)
    y = ops.where(x <= 0.04045, x / 12.92, ((ops.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4)
    return y.astype(np.float32) if ops.name == "numpy" else y


def linear_to_srgb(x: Any) -> Any:
    """Linear values (clipped to [0, 1]) -> sRGB-encoded values in [0, 1].

    Written once over :mod:`pgc.arrays`: torch and JAX arrays keep their dtype (differentiable, finite gradient
    at 0); anything else is computed in float64 and returned as float32 numpy (PGC's image values)."""
    ops, x = float_operands(x)
    x = ops.clip(x, 0.0, 1.0)
    y = ops.where(x <= 0.0031308, 12.92 * x, 1.055 * ops.maximum(x, 0.0031308) ** (1.0 / 2.4) - 0.055)
    return y.astype(np.float32) if ops.name == "numpy" else y


def _require_finite(path: Path, values: np.ndarray) -> None:
    """PNG cannot hold NaN/Inf: refuse them instead of clipping them into valid-looking pixels."""
    if not np.all(np.isfinite(values)):
        bad = int(np.size(values) - np.count_nonzero(np.isfinite(values)))
        raise PGCDataError(f"{path}: refusing to write {bad} non-finite values (NaN or Inf) to a PNG; fix the data "
                           "(or write EXR)")


def _quantize(values01: np.ndarray, bits: int) -> np.ndarray:
    """PNG code values of ``values01`` (clipped to [0, 1])."""
    if bits not in (8, 16):
        raise ValueError(f"PNG bit depth must be 8 or 16, got {bits}")
    top = (1 << bits) - 1
    q = np.rint(np.clip(values01, 0.0, 1.0) * top)
    return q.astype(np.uint8 if bits == 8 else np.uint16)


def _png_header(path: Path) -> tuple[int, int]:
    """(bit depth, colour type) from the IHDR chunk of a PNG file, after checking its size against
    :data:`pgc.io.limits.MAX_IMAGE_PIXELS` (nothing is decoded before that)."""
    with open(path, "rb") as f:
        head = f.read(33)
    if len(head) < 33 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise PGCDataError(f"{path}: not a PNG file (bad signature or header)")
    width, height = struct.unpack(">II", head[16:24])
    limits.check_pixels(path, width, height, "PNG header (IHDR) size")
    return head[24], head[25]


def _exr_size(path: Path) -> tuple[int, int]:
    """(width, height) of an EXR file's data window, checked against the pixel limit, from its header."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path), header_only=True) as f:
            (x0, y0), (x1, y1) = f.header()["dataWindow"]
    except Exception as exc:  # OpenEXR raises plain RuntimeError on bad files
        raise _bad_exr(path, exc) from None
    width, height = int(x1) - int(x0) + 1, int(y1) - int(y0) + 1
    limits.check_pixels(path, width, height, "EXR header dataWindow")
    return width, height


def _pil_open(path: Path):
    """``PIL.Image.open`` whose size is checked against the pixel limit before anything is decoded."""
    from PIL import Image

    try:
        im = Image.open(path)
    except Image.DecompressionBombError as exc:
        raise limits.fail(path, "image size", f"more pixels than PGC reads (the limit is {limits.MAX_IMAGE_PIXELS}; "
                                              f"{exc})") from None
    try:
        limits.check_pixels(path, *im.size)
    except PGCDataError:
        im.close()
        raise
    return im


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - cv2 is part of the [opencv] extra
        raise PGCPluginError("16-bit colour PNG needs OpenCV: pip install 'pgc[opencv]'") from exc
    return cv2


def _read_png_codes(path: Path) -> tuple[np.ndarray, int]:
    """Raw PNG code values (H, W) or (H, W, C) with C in 1..4, and the bit depth (8 or 16)."""
    depth, colour_type = _png_header(path)
    if depth == 16 and colour_type in (2, 6):  # 16-bit RGB(A): Pillow would truncate it to 8 bits
        cv2 = _cv2()
        arr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if arr is None:
            raise PGCDataError(f"{path}: cannot decode PNG")
        arr = arr[..., [2, 1, 0, 3][: arr.shape[2]]]
        return np.ascontiguousarray(arr), 16
    try:
        with _pil_open(path) as im:
            if im.mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            elif im.mode == "1":
                im = im.convert("L")
            arr = np.asarray(im)
    except OSError as exc:
        raise PGCDataError(f"{path}: cannot decode PNG ({exc})") from exc
    if arr.dtype == np.uint8:
        return arr, 8
    if arr.dtype in (np.uint16, np.int32) and arr.ndim == 2:  # Pillow: 'I;16' or 'I'
        return arr.astype(np.uint16), 16
    raise PGCDataError(f"{path}: unsupported PNG pixel format {arr.dtype} {arr.shape}")


def _write_png_codes(path: Path, codes: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        if codes.dtype == np.uint16 and codes.ndim == 3:
            cv2 = _cv2()
            bgr = codes[..., [2, 1, 0, 3][: codes.shape[2]]]
            if not cv2.imwrite(str(tmp), np.ascontiguousarray(bgr)):
                raise OSError(f"OpenCV could not write {path}")
        else:
            from PIL import Image

            Image.fromarray(np.ascontiguousarray(codes)).save(tmp, format="PNG")


def read_exr(path: str | os.PathLike) -> np.ndarray:
    """An EXR file as float32: (H, W) for a single channel (Y or Z), else (H, W, C) in R, G, B[, A] order."""
    import OpenEXR

    path = Path(path)
    _require_file(path)
    _exr_size(path)
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            channels = {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
    except Exception as exc:  # OpenEXR raises plain RuntimeError on bad files
        raise _bad_exr(path, exc) from None
    if len(channels) == 1:
        return next(iter(channels.values()))
    order = [c for c in ("R", "G", "B", "A") if c in channels]
    if len(order) != len(channels):
        raise PGCDataError(f"{path}: EXR channels {sorted(channels)} are not a subset of R, G, B, A "
                           "(or one single channel)")
    return np.stack([channels[c] for c in order], axis=-1)


def read_envmap(path: str | os.PathLike) -> np.ndarray:
    """The (H, 2H, 3) float32 radiance of the environment map EXR at ``path`` (latitude-longitude, +Y up; an
    alpha channel dropped), or a :class:`PGCDataError` naming the file and its problem: its shape, non-finite
    values (with the count) or negative radiance."""
    from pgc.checks import require_finite

    env = read_exr(path)
    if env.ndim != 3 or env.shape[2] not in (3, 4) or env.shape[1] != 2 * env.shape[0] or env.shape[0] == 0:
        raise PGCDataError(f"{path}: an environment map must be a latitude-longitude RGB image of H x 2H pixels, "
                           f"got shape {env.shape}; re-export it as an equirectangular RGB EXR")
    env = env[..., :3]
    require_finite(str(path), "the environment map", env,
                   "replace them (clamp or inpaint those pixels) and re-export the file")
    if (env < 0).any():
        raise PGCDataError(f"{path}: {int((env < 0).sum())} negative radiance values in the environment map; "
                           "radiance must be >= 0")
    return np.ascontiguousarray(env)


def _bad_exr(path: Path, exc: Exception) -> PGCDataError:
    return PGCDataError(f"{path}: the file exists ({path.stat().st_size} bytes) but is not a readable OpenEXR image "
                        f"(corrupt, truncated or another format; the decoder said: {exc}); re-export it as EXR")


def write_exr(path: str | os.PathLike, array: np.ndarray) -> None:
    """Write (H, W) as channel Y, or (H, W, 3|4) as R, G, B[, A]; float32, ZIP-compressed, lossless."""
    import OpenEXR

    a = np.ascontiguousarray(np.asarray(array, dtype=np.float32))
    if a.ndim == 2:
        channels = {"Y": a}
    elif a.ndim == 3 and a.shape[2] in (3, 4):
        channels = {c: np.ascontiguousarray(a[..., i]) for i, c in enumerate("RGBA"[: a.shape[2]])}
    else:
        raise ValueError(f"EXR layers must be (H, W) or (H, W, 3|4), got {a.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))


def _require_file(path: Path) -> None:
    if not path.is_file():
        raise PGCDataError(f"{path}: file not found")


def _suffix(path: Path) -> str:
    s = path.suffix.lower()
    if s not in EXR_SUFFIXES + PNG_SUFFIXES + (".jpg", ".jpeg"):
        raise PGCDataError(f"{path}: unsupported image type '{s}' (use .png, .exr or .jpg)")
    return s


def read_image(path: str | os.PathLike) -> np.ndarray:
    """A colour image as float32 linear RGB (H, W, 3).

    PNG/JPEG are decoded from sRGB; EXR is taken as linear. An alpha channel is dropped; a grey
    image is repeated to three channels.
    """
    path = Path(path)
    _require_file(path)
    if _suffix(path) in EXR_SUFFIXES:
        a = read_exr(path)
    elif path.suffix.lower() in PNG_SUFFIXES:
        codes, bits = _read_png_codes(path)
        lut = srgb_to_linear(np.arange(1 << bits, dtype=np.float64) / ((1 << bits) - 1))
        a = lut[codes]
    else:
        from PIL import Image, UnidentifiedImageError

        try:
            with _pil_open(path) as im:
                a = srgb_to_linear(np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0)
        except (UnidentifiedImageError, OSError, ValueError) as exc:
            raise PGCDataError(f"{path}: cannot decode the image ({exc}); re-export it") from None
    if a.ndim == 2 or a.shape[2] == 2:  # grey, or grey + alpha
        a = np.repeat(a[..., :1] if a.ndim == 3 else a[..., None], 3, axis=2)
    if a.shape[2] == 4:
        a = a[..., :3]
    if a.shape[2] != 3:
        raise PGCDataError(f"{path}: expected a colour image, got {a.shape[2]} channels")
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        row, col = np.argwhere(~np.isfinite(a))[0, :2]
        raise PGCDataError(f"{path}: {bad} non-finite values (NaN or Inf; first at pixel x={col} y={row}); every "
                           "pixel must be a finite colour: fix or re-export the image")
    return np.ascontiguousarray(a, dtype=np.float32)


def write_image(path: str | os.PathLike, image: np.ndarray, bits: int = 8) -> None:
    """Write linear RGB (H, W, 3): PNG as sRGB with ``bits`` 8 or 16 (clipped to [0, 1]), EXR as float32."""
    path = Path(path)
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"{path}: image must be (H, W, 3), got {image.shape}")
    if _suffix(path) in EXR_SUFFIXES:
        write_exr(path, image)
    elif path.suffix.lower() in PNG_SUFFIXES:
        _require_finite(path, image)
        _write_png_codes(path, _quantize(linear_to_srgb(image), bits))
    else:
        raise PGCDataError(f"{path}: writing JPEG is not supported (lossy); use .png or .exr")


def read_mask(path: str | os.PathLike) -> np.ndarray:
    """A grey mask as float32 (H, W) in [0, 1] (PNG code / max code, or EXR values as stored).

    A colour PNG is accepted only when its colour channels are equal (its alpha is ignored).
    """
    path = Path(path)
    _require_file(path)
    if _suffix(path) in EXR_SUFFIXES:
        m = read_exr(path)
        if m.ndim == 3:
            raise PGCDataError(f"{path}: a mask must have one channel, got {m.shape[2]}")
        return m
    codes, bits = _read_png_codes(path)
    if codes.ndim == 3:
        if codes.shape[2] == 2:  # grey + alpha
            codes = codes[..., 0]
        elif np.array_equal(codes[..., 0], codes[..., 1]) and np.array_equal(codes[..., 0], codes[..., 2]):
            codes = codes[..., 0]
        else:
            raise PGCDataError(f"{path}: a mask must be a grey image; this PNG has differing colour channels")
    return (codes.astype(np.float32) / np.float32((1 << bits) - 1)).astype(np.float32)


def write_mask(path: str | os.PathLike, mask: np.ndarray, bits: int = 8) -> None:
    """Write a (H, W) mask in [0, 1] as a grey PNG of ``bits`` 8 or 16 (or EXR, float32)."""
    path = Path(path)
    mask = np.asarray(mask, dtype=np.float32)
    if mask.ndim != 2:
        raise ValueError(f"{path}: mask must be (H, W), got {mask.shape}")
    if _suffix(path) in EXR_SUFFIXES:
        write_exr(path, mask)
    else:
        _require_finite(path, mask)
        _write_png_codes(path, _quantize(mask, bits))


def read_labels(path: str | os.PathLike) -> np.ndarray:
    """An 8-bit label map (H, W) uint8 from a grey PNG."""
    path = Path(path)
    _require_file(path)
    if path.suffix.lower() not in PNG_SUFFIXES:
        raise PGCDataError(f"{path}: label maps must be PNG files")
    codes, bits = _read_png_codes(path)
    if codes.ndim != 2 or bits != 8:
        raise PGCDataError(f"{path}: a label map must be an 8-bit grey PNG, got {bits}-bit with shape "
                           f"{codes.shape}")
    return codes.astype(np.uint8)


def write_labels(path: str | os.PathLike, labels: np.ndarray) -> None:
    """Write a (H, W) label map of ids 0..255 as an 8-bit grey PNG."""
    labels = np.asarray(labels)
    if labels.ndim != 2:
        raise ValueError(f"{path}: labels must be (H, W), got {labels.shape}")
    if labels.size and (labels.min() < 0 or labels.max() > 255):
        raise ValueError(f"{path}: label ids must be in 0..255")
    _write_png_codes(Path(path), labels.astype(np.uint8))


def image_size(path: str | os.PathLike) -> tuple[int, int]:
    """(width, height) of a PNG/JPEG/EXR file without decoding its pixels."""
    path = Path(path)
    _require_file(path)
    if _suffix(path) in EXR_SUFFIXES:
        return _exr_size(path)
    try:
        with _pil_open(path) as im:
            return im.size
    except PGCDataError:
        raise
    except (OSError, ValueError) as exc:
        raise PGCDataError(f"{path}: cannot read image ({exc})") from exc


def undistort(array: np.ndarray, K: np.ndarray, dist: np.ndarray, interpolation: str = "linear") -> np.ndarray:
    """Resample an image (H, W[, C]) taken with OpenCV distortion ``dist`` to the pinhole camera ``K``.

    ``K`` uses PGC/COLMAP pixel centres (integer + 0.5); OpenCV's are integers, hence the half-pixel shift.
    Pixels whose source falls outside the image are 0.
    """
    try:
        import cv2
    except ImportError as exc:
        raise PGCPluginError("undistorting images needs OpenCV: pip install 'pgc[opencv]'") from exc
    h, w = array.shape[:2]
    K_cv = np.array(K, dtype=np.float64)
    K_cv[:2, 2] -= 0.5
    map_x, map_y = cv2.initUndistortRectifyMap(K_cv, np.asarray(dist, np.float64), None, K_cv, (w, h), cv2.CV_32FC1)
    flag = cv2.INTER_NEAREST if interpolation == "nearest" else cv2.INTER_LINEAR
    return cv2.remap(array, map_x, map_y, flag, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
