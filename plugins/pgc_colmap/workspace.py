"""Files of a COLMAP workspace made from a PGC capture: the images, and dense depth/normal maps in COLMAP's
binary format (so that COLMAP's CPU fusion can use our depth maps).

COLMAP's camera convention equals PGC's (OpenCV, world-to-camera, pixel centres at integer + 0.5), so K, R
and t carry over unchanged.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pgc.io.images import write_image
from pgc.types import Capture


def image_names(capture: Capture) -> list[str]:
    """File names of the views inside the workspace (index-prefixed, so they sort in capture order)."""
    return [f"{i:04d}.png" for i in range(len(capture.views))]


def write_images(capture: Capture, folder: Path) -> list[str]:
    folder.mkdir(parents=True, exist_ok=True)
    names = image_names(capture)
    for name, view in zip(names, capture.views):
        write_image(folder / name, view.image)
    return names


def write_dense_array(path: Path, array: np.ndarray) -> None:
    """COLMAP's dense map format: ``width&height&channels&`` then float32 values, one plane per channel,
    each plane row by row (x fastest): the (width, height, channels) array in Fortran order."""
    a = np.asarray(array, np.float32)
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    with open(path, "wb") as f:
        f.write(f"{w}&{h}&{c}&".encode())
        np.transpose(a, (1, 0, 2)).reshape(-1, order="F").tofile(f)


def read_dense_array(path: Path) -> np.ndarray:
    """Inverse of :func:`write_dense_array`: (H, W) or (H, W, C) float32."""
    with open(path, "rb") as f:
        header = b""
        while header.count(b"&") < 3:
            header += f.read(1)
        w, h, c = (int(x) for x in header.decode().split("&")[:3])
        data = np.fromfile(f, np.float32)
    a = np.transpose(data.reshape((w, h, c), order="F"), (1, 0, 2))
    return a[..., 0] if c == 1 else a
