"""Backend-neutral pieces of the splat fit schedule (numpy): initial count, SH and learning-rate schedules,
contour-band weights, held-out split, back-facing faces, checkpoint fingerprint.

They follow the ``fit_splats`` settings (:mod:`pgc.pipeline.settings_splats`) exactly as the torch fit does;
they belong in ``pgc/splats`` so that both backends share one copy (see docs/splats_jax.md).
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np

from pgc.pipeline.settings_splats import FitSplatsSettings
from pgc.types import Camera, Capture, Mesh

PAPER_ITERATIONS = 30000


def initial_count(capture: Capture, s: FitSplatsSettings) -> int:
    """``gaussians_per_pixel`` x mean foreground pixels per view x 2 (front and back), clamped."""
    covered = [float(np.sum(v.mask > 0.5)) if v.mask is not None else v.camera.width * v.camera.height
               for v in capture.views]
    return int(np.clip(round(s.gaussians_per_pixel * 2.0 * np.mean(covered)), s.min_gaussians, s.max_gaussians))


def sh_degree_at(step: int, total: int | None, s: FitSplatsSettings) -> int:
    """SH degree at ``step``: raised every ``sh_interval`` steps, the interval scaled from the paper's 30000."""
    interval = max(1, round(s.sh_interval * (total or PAPER_ITERATIONS) / PAPER_ITERATIONS))
    return min(s.max_sh_degree, step // interval)


def position_lr_at(step: int, total: int | None, s: FitSplatsSettings) -> float:
    """Exponential decay of the local-position learning rate from ``lr_position`` to ``lr_position_final``."""
    t = min(1.0, step / max(1, (total or PAPER_ITERATIONS) - 1))
    return math.exp((1 - t) * math.log(s.lr_position) + t * math.log(s.lr_position_final))


def outside_band(mask: np.ndarray, band: float) -> np.ndarray:
    """(H, W) float32: 1 outside the contour band of ``mask``, 0 inside it (the band lies between the erosion
    and the dilation of the binarised mask by a square of side ``band * H``, odd, >= 1)."""
    from scipy.ndimage import binary_dilation, binary_erosion

    side = max(1, int(round(band * mask.shape[0])) | 1)
    m = np.asarray(mask) > 0.5
    square = np.ones((side, side), bool)
    ring = binary_dilation(m, square) != binary_erosion(m, square, border_value=1)
    return (~ring).astype(np.float32)


def heldout_split(n_views: int, every: int) -> tuple[list[int], list[int]]:
    """(train, held-out) view indices: every ``every``-th view is held out when there are >= 2 x every views."""
    held = list(range(every - 1, n_views, every)) if n_views >= 2 * every else []
    return [i for i in range(n_views) if i not in held], held


def backfacing_faces(mesh: Mesh, cameras: list[Camera]) -> np.ndarray:
    """(F,) True for faces whose front side faces no camera."""
    centroids = mesh.vertices[mesh.faces].mean(1)
    normals = mesh.face_normals()
    seen = np.zeros(len(mesh.faces), bool)
    for cam in cameras:
        seen |= np.sum(normals * (cam.center - centroids), axis=1) > 0
    return ~seen


def fingerprint(capture: Capture, mesh: Mesh, s: FitSplatsSettings, backend: str) -> str:
    """Hash of what a checkpoint depends on (mesh, views, settings other than logging/checkpointing)."""
    h = hashlib.sha256(backend.encode())
    h.update(np.ascontiguousarray(mesh.vertices).tobytes() + np.ascontiguousarray(mesh.faces).tobytes())
    h.update(json.dumps([v.camera.name for v in capture.views]).encode())
    h.update(json.dumps(s.model_dump(exclude={"checkpoint_dir", "checkpoint_every", "log_every"}), sort_keys=True,
                        default=str).encode())
    return h.hexdigest()[:20]
