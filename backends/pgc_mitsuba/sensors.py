"""Two Python sensors for Mitsuba: an exact OpenCV pinhole, and rays gathered from arrays.

``pgc_pinhole``: the :class:`pgc.types.Camera` model exactly (full K including fx != fy, skew and the
principal point; pixel (0, 0) covers [0, 1)^2, samples jittered uniformly inside each pixel with a box
filter). Mitsuba's ``perspective`` has a single field of view, so it cannot represent every calibrated K.
Several cameras of one size can share one film side by side, so that one render call (one traced
kernel) covers many views: the material fit renders all its views in every step this way.

``pgc_rays``: a K x 1 film whose pixel k traces the ray (origins[k], directions[k]); used for texture-space
rendering (one ray per texel). Both are registered on first use.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.types import Camera
from pgc_mitsuba.runtime import mitsuba

_registered = False


def _register() -> None:
    global _registered
    if _registered:
        return
    mi = mitsuba()
    import drjit as dr

    class PinholeSensor(mi.Sensor):
        """OpenCV pinholes tiled side by side on one film: film column x belongs to camera x // W."""

        def __init__(self, props: Any) -> None:
            mi.Sensor.__init__(self, props)
            self.tile_width = 1
            self.matrices = mi.Float(0.0)  # per camera: R^T K^-1 (9 values, row-major)
            self.centres = mi.Float(0.0)  # per camera: centre (3 values)

        def set_cameras(self, cameras: list[Camera], tile_width: int) -> None:
            self.tile_width = int(tile_width)
            self.matrices = mi.Float(np.concatenate([(c.R.T @ np.linalg.inv(c.K)).reshape(-1) for c in cameras]))
            self.centres = mi.Float(np.concatenate([c.center for c in cameras]))

        def sample_ray(self, time: Any, sample1: Any, sample2: Any, sample3: Any, active: bool = True) -> Any:
            size = self.film().size()
            x, py = sample2.x * float(size.x), sample2.y * float(size.y)
            cam = mi.UInt32(dr.floor(x / float(self.tile_width)))
            px = x - mi.Float(cam) * float(self.tile_width)
            m = [dr.gather(mi.Float, self.matrices, cam * 9 + i, active) for i in range(9)]
            c = [dr.gather(mi.Float, self.centres, cam * 3 + i, active) for i in range(3)]
            d = mi.Vector3f(*(m[3 * i] * px + m[3 * i + 1] * py + m[3 * i + 2] for i in range(3)))
            return mi.Ray3f(mi.Point3f(*c), dr.normalize(d), time, mi.Color0f()), mi.Color3f(1.0)

        def sample_ray_differential(self, time: Any, sample1: Any, sample2: Any, sample3: Any,
                                    active: bool = True) -> Any:
            ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
            return mi.RayDifferential3f(ray), weight

        def to_string(self) -> str:
            return "PGCPinholeSensor[]"

    class RaySensor(mi.Sensor):
        """Pixel k of a K x 1 film traces (origins[k], directions[k])."""

        def __init__(self, props: Any) -> None:
            mi.Sensor.__init__(self, props)
            self.origins = mi.Point3f(0.0)
            self.directions = mi.Vector3f(0.0, 0.0, 1.0)

        def set_rays(self, origins: np.ndarray, directions: np.ndarray) -> None:
            self.origins = mi.Point3f(np.ascontiguousarray(origins, dtype=np.float32).T)
            self.directions = mi.Vector3f(np.ascontiguousarray(directions, dtype=np.float32).T)

        def sample_ray(self, time: Any, sample1: Any, sample2: Any, sample3: Any, active: bool = True) -> Any:
            n = self.film().size().x
            idx = mi.UInt32(dr.minimum(sample2.x * float(n), float(n - 1)))
            o = dr.gather(mi.Point3f, self.origins, idx, active)
            d = dr.gather(mi.Vector3f, self.directions, idx, active)
            return mi.Ray3f(o, d, time, mi.Color0f()), mi.Color3f(1.0)

        def sample_ray_differential(self, time: Any, sample1: Any, sample2: Any, sample3: Any,
                                    active: bool = True) -> Any:
            ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
            return mi.RayDifferential3f(ray), weight

        def to_string(self) -> str:
            return "PGCRaySensor[]"

    mi.register_sensor("pgc_pinhole", lambda props: PinholeSensor(props))
    mi.register_sensor("pgc_rays", lambda props: RaySensor(props))
    _registered = True


def _film(width: int, height: int, alpha: bool) -> dict[str, Any]:
    return {"type": "hdrfilm", "width": int(width), "height": int(height), "rfilter": {"type": "box"},
            "pixel_format": "rgba" if alpha else "rgb", "sample_border": False}


def pinhole_sensor(cameras: Camera | list[Camera], spp: int, sampler: str = "independent") -> Any:
    """A sensor rendering ``cameras`` (one, or several of one image size tiled left to right on one RGBA
    film: camera k owns film columns [k W, (k + 1) W)) with ``spp`` samples per pixel of Mitsuba's
    ``sampler``."""
    _register()
    mi = mitsuba()
    cameras = [cameras] if isinstance(cameras, Camera) else list(cameras)
    width, height = cameras[0].width, cameras[0].height
    if any((c.width, c.height) != (width, height) for c in cameras):
        raise PGCDataError("pinhole_sensor: tiled cameras must share one image size, got "
                           f"{sorted({(c.width, c.height) for c in cameras})}")
    sensor = mi.load_dict({"type": "pgc_pinhole", "film": _film(width * len(cameras), height, True),
                           "sampler": {"type": sampler, "sample_count": int(spp)}})
    sensor.set_cameras(cameras, width)
    return sensor


def ray_sensor(origins: np.ndarray, directions: np.ndarray, spp: int) -> Any:
    """A sensor tracing the given (K, 3) rays into a K x 1 RGBA film (alpha: the ray hit something)."""
    _register()
    mi = mitsuba()
    sensor = mi.load_dict({"type": "pgc_rays", "film": _film(len(origins), 1, True),
                           "sampler": {"type": "independent", "sample_count": int(spp)}})
    sensor.set_rays(origins, directions)
    return sensor
