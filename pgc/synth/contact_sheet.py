"""A contact sheet of a capture: every view's colour image beside its segmentation over the mask."""

from __future__ import annotations

import os

import numpy as np

from pgc.types import View

LABEL_COLORS = np.array([[0.0, 0.0, 0.0], [0.8, 0.45, 0.3], [0.1, 0.35, 0.9]], np.float32)
"""Linear RGB of segmentation labels 0 (background), 1 (body), 2 (garment)."""


def contact_sheet(views: list[View], tile: int = 128, columns: int | None = None) -> np.ndarray:
    """(H, W, 3) linear RGB grid: per view the image and the segmentation colours times the mask."""
    import cv2

    cells = []
    for v in views:
        img = cv2.resize(np.asarray(v.image, np.float32), (tile, tile), interpolation=cv2.INTER_AREA)
        seg = LABEL_COLORS[np.minimum(v.segmentation, len(LABEL_COLORS) - 1)] if v.segmentation is not None \
            else np.zeros(v.image.shape, np.float32)
        mask = v.mask if v.mask is not None else np.ones(v.image.shape[:2], np.float32)
        seg = cv2.resize(seg * (0.25 + 0.75 * mask[..., None]), (tile, tile), interpolation=cv2.INTER_NEAREST)
        pair = np.concatenate([img, seg], axis=1)
        pair[:, :1] = pair[:1] = 1.0  # thin separators
        cells.append(pair)
    columns = columns or max(1, int(np.ceil(np.sqrt(len(cells) / 2))))
    rows = int(np.ceil(len(cells) / columns))
    sheet = np.ones((rows * tile, columns * 2 * tile, 3), np.float32)
    for i, cell in enumerate(cells):
        r, c = divmod(i, columns)
        sheet[r * tile:(r + 1) * tile, c * 2 * tile:(c + 1) * 2 * tile] = cell
    return sheet


def write_contact_sheet(path: str | os.PathLike, views: list[View], tile: int = 128) -> None:
    """Write :func:`contact_sheet` as an sRGB PNG."""
    from pgc.io.images import write_image

    write_image(path, contact_sheet(views, tile))
