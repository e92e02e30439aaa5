"""The data of material fitting: capture views at fitting resolution, the garment pixels that count, and
the error measure (numpy; shared by the Mitsuba fit and by model selection)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pgc.errors import PGCDataError
from pgc.types import Camera, Capture, Light, Mesh, View

INTERIOR = 0.999
"""A pixel counts when at least this fraction of it and of each of its 8 neighbours is garment: silhouette
pixels mix the garment with the background (a hard segmentation label does not show it), and there the
view is grazing, so a sheen lobe could "explain" the background's colour."""


@dataclass
class FitView:
    camera: Camera
    """The camera at fitting resolution."""
    target: np.ndarray
    """(H, W, 3) float32 linear image."""
    weight: np.ndarray
    """(H, W) float32: 1 on interior garment pixels, 0 elsewhere."""
    name: str


def _block_mean(a: np.ndarray, f: int) -> np.ndarray:
    h, w = a.shape[0] // f * f, a.shape[1] // f * f
    a = a[:h, :w]
    return a.reshape(h // f, f, w // f, f, *a.shape[2:]).mean(axis=(1, 3))


def _erode(inside: np.ndarray) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood lies inside (image borders count as outside)."""
    padded = np.pad(inside, 1, constant_values=False)
    h, w = inside.shape
    out = np.ones_like(inside)
    for dy in range(3):
        for dx in range(3):
            out &= padded[dy:dy + h, dx:dx + w]
    return out


def garment_fraction(view: View, garment_ids: list[int]) -> np.ndarray:
    """(H, W) garment coverage of a view: from the segmentation, else the foreground mask, else all ones."""
    if view.segmentation is not None:
        return np.isin(view.segmentation, garment_ids).astype(np.float32)
    if view.mask is not None:
        return view.mask.astype(np.float32)
    return np.ones((view.camera.height, view.camera.width), dtype=np.float32)


def prepare_views(capture: Capture, max_side: int, views: list[int] | None = None) -> list[FitView]:
    """The views (indices ``views``, default all) area-downsampled by an integer factor so that their
    longer side is at most ``max_side``, with their interior-garment weights."""
    ids = capture.garment_label_ids
    out = []
    for i in (range(len(capture.views)) if views is None else views):
        view = capture.views[i]
        cam = view.camera
        f = max(1, math.ceil(max(cam.width, cam.height) / max_side))
        K = cam.K.copy()
        K[:2] /= f
        small = replace(cam, K=K, width=cam.width // f, height=cam.height // f)
        weight = _erode(_block_mean(garment_fraction(view, ids), f) >= INTERIOR).astype(np.float32)
        out.append(FitView(small, _block_mean(view.image, f).astype(np.float32), weight, cam.name))
    if not any(v.weight.any() for v in out):
        raise PGCDataError("capture: no view has garment pixels (check the segmentation labels "
                           f"{capture.labels} and the masks)")
    return out


@dataclass(frozen=True)
class FitLight:
    """The light a material fit renders under: its shape and where it came from."""

    shape: Light
    """Unit radiance times the capture's environment map (with its rotation), or a unit constant."""
    radiance: np.ndarray
    """(3,) the initial RGB radiance: the capture's recorded one, else 1 (the paper's initial value)."""
    source: str
    """'capture' (the capture's recorded light) or 'constant' (a constant environment assumed)."""

    def light(self, radiance: np.ndarray) -> Light:
        """The shape at RGB ``radiance``."""
        return Light(np.asarray(radiance, np.float64), self.shape.envmap, self.shape.rotation_deg)

    def record(self) -> dict:
        """For the fit's figures: the source, the kind of light and the environment map's size."""
        env = self.shape.envmap
        return {"source": self.source, "kind": "constant" if env is None else "envmap",
                "envmap_shape": None if env is None else list(np.shape(env)),
                "rotation_deg": float(self.shape.rotation_deg)}


def fit_light(capture: Capture, mode: str) -> FitLight:
    """The light a material fit of ``capture`` renders under, for ``MaterialFitSettings.light`` ``mode``
    ('auto', 'capture' or 'constant'; see there). 'capture' on a capture that records no light is a
    :class:`PGCDataError` naming the fix."""
    known = capture.light
    if mode == "capture" and known is None:
        where = capture.root or "the capture"
        raise PGCDataError(f"{where}: stages.material.light = 'capture' but the capture records no light "
                           "(transforms.json has no 'pgc_light'); set stages.material.light = 'auto' or "
                           "'constant' to fit a constant environment, or record the capture's light")
    if mode not in ("auto", "capture", "constant"):
        raise PGCDataError(f"stages.material.light: unknown mode '{mode}'; use 'auto', 'capture' or 'constant'")
    if known is None or mode == "constant":
        return FitLight(Light(np.ones(3)), np.ones(3), "constant")
    return FitLight(Light(np.ones(3), known.envmap, known.rotation_deg), np.asarray(known.radiance, np.float64),
                    "capture")


def masked_mse(pred: np.ndarray, target: np.ndarray, weight: np.ndarray) -> float:
    w = weight[..., None]
    return float(np.sum(w * (pred - target) ** 2) / max(3.0 * float(weight.sum()), 1.0))


def psnr_from_mse(mse: float, peak: float = 1.0) -> float:
    """PSNR in dB of a mean squared error (linear radiance, ``peak`` 1); inf for zero error."""
    return float("inf") if mse <= 0 else float(10.0 * np.log10(peak * peak / mse))


def split_occluders(mesh: Mesh, garment_labels: tuple[int, ...] | None) -> tuple[Mesh, Mesh | None]:
    """(garment part, occluder part or None) of ``mesh`` by face label; all faces are garment when
    ``garment_labels`` is None or the mesh has no labels."""
    if garment_labels is None or mesh.face_labels is None:
        return mesh, None
    is_garment = np.isin(mesh.face_labels, np.asarray(garment_labels))
    if not is_garment.any():
        raise PGCDataError(f"mesh '{mesh.name}' has no faces with a garment label {list(garment_labels)}")
    garment, _ = mesh.submesh(is_garment)
    occluder = mesh.submesh(~is_garment)[0] if (~is_garment).any() else None
    return garment, occluder
