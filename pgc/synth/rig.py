"""The capture rig: cameras on a half dome around the person, the capture light and the relighting maps.

A real capture dome (the paper's: 170 cameras on a half dome, 4096x2668, about 2.5-3 m from the subject,
focal lengths framing the whole person) scaled down: C cameras on rings of a hemisphere centred at the
body's mid-height, every camera looking at the body centre, the focal length chosen so the whole person
(bounding sphere of ``subject_radius``) fits each image with a margin. Cameras are OpenCV (x right, y
down, z forward), world-to-camera; world +Y is up.
"""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.sampling import envmap_directions, fibonacci_sphere
from pgc.types import Camera, Light, look_at_pose

DEFAULT_RADIANCE = (1.0, 0.96, 0.9)
"""The constant capture light: a slightly warm white of known RGB radiance."""


def dome_cameras(count: int = 32, width: int = 256, height: int = 256, center: tuple[float, float, float] = (0, 0.9, 0),
                 distance: float = 2.6, subject_radius: float = 0.9, margin: float = 1.04,
                 elevations_deg: tuple[float, ...] = (-10.0, 10.0, 30.0, 55.0), seed: int = 0) -> list[Camera]:
    """``count`` cameras on a half dome of radius ``distance`` around ``center`` (rings at the given
    elevations, the last ring sparser, azimuths staggered between rings, slightly jittered by ``seed``).

    The focal length makes a sphere of ``subject_radius`` (times ``margin``) fit the shorter image side.
    """
    if count < 1 or width < 8 or height < 8:
        raise PGCDataError(f"dome_cameras: need count >= 1 and images of at least 8x8, got {count}, {width}x{height}")
    if distance <= subject_radius * margin:
        raise PGCDataError(f"dome_cameras: distance {distance} m must exceed the subject radius {subject_radius} m")
    rng = np.random.default_rng(seed)
    share = count * np.cos(np.deg2rad(elevations_deg)) / np.cos(np.deg2rad(elevations_deg)).sum()
    per_ring = np.floor(share).astype(int)  # largest remainders get the cameras left over
    per_ring[np.argsort(-(share - per_ring), kind="stable")[:count - per_ring.sum()]] += 1
    half_angle = np.arcsin(min(subject_radius * margin / distance, 0.99))
    focal = 0.5 * min(width, height) / np.tan(half_angle)
    K = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1]])
    center = np.asarray(center, float)
    cams: list[Camera] = []
    for ring, (elev, n) in enumerate(zip(elevations_deg, per_ring)):
        for k in range(n):  # empty rings (few cameras) are skipped
            az = 2 * np.pi * (k + 0.5 * (ring % 2)) / n + rng.uniform(-0.03, 0.03)
            el = np.deg2rad(elev) + rng.uniform(-0.02, 0.02)
            eye = center + distance * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
            R, t = look_at_pose(eye, center)
            cams.append(Camera(K, R, t, width, height, name=f"cam{len(cams):03d}"))
    return cams


CAPTURE_LIGHTS = ("uniform", "sky-sun")
"""The capture lights of :func:`capture_light` (docs/pbr.md, "A capture light that identifies the material")."""

SUN_ELEVATION_DEG = 40.0
SUN_AZIMUTH_DEG = 30.0
"""The sky-sun capture light's sun: elevation above the horizon and azimuth from +Z toward +X, degrees."""
SUN_RADIUS_DEG = 3.0
SUN_FRACTION = 0.6
"""The sun's share of the irradiance on an upward-facing surface."""


def capture_light(kind: str = "uniform", radiance: tuple[float, float, float] = DEFAULT_RADIANCE,
                  envmap_height: int = 64) -> Light:
    """The capture dome's light, known to the material fit: 'uniform', a constant environment of
    ``radiance``; 'sky-sun', ``radiance`` times :func:`sky_sun_envmap` (a bluish sky brightening to the
    zenith, a dim ground and a sun; exposed so that no face receives more irradiance than under the uniform
    light)."""
    if kind == "uniform":
        return Light(radiance=np.asarray(radiance, float))
    if kind == "sky-sun":
        return Light(radiance=np.asarray(radiance, float), envmap=sky_sun_envmap(envmap_height))
    raise PGCDataError(f"unknown capture light '{kind}'; use one of: {', '.join(CAPTURE_LIGHTS)}")


def sky_sun_envmap(height: int = 64) -> np.ndarray:
    """The sky-sun capture environment (height, 2 height, 3) float32: sky radiance 0.2 below the horizon
    rising to 1 at the zenith, tinted (0.8, 0.9, 1.1); a sun disc of ``SUN_RADIUS_DEG`` (at least one pixel)
    at ``SUN_ELEVATION_DEG`` / ``SUN_AZIMUTH_DEG`` carrying ``SUN_FRACTION`` of the irradiance on an
    upward face. Exposed as the uniform light is: the brightest irradiance on any unoccluded face (green) is
    pi, that of the uniform environment of radiance 1, so a white Lambertian face is at most radiance 1 under
    either light (the capture's 8-bit images clip at 1; scaled to mean radiance 1 instead, 11-23 % of the
    garment's pixels in sun-lit views clipped)."""
    if height < 8:
        raise PGCDataError(f"sky_sun_envmap: need a height of at least 8 pixels, got {height}")
    d, solid = envmap_directions(height, 2 * height)
    d, solid = d.reshape(height, 2 * height, 3), solid.reshape(height, 2 * height)
    up = d[..., 1]
    sky = (0.2 + 0.8 * np.clip(up, 0.0, 1.0))[..., None] * np.array([0.8, 0.9, 1.1])
    e, a = np.deg2rad(SUN_ELEVATION_DEG), np.deg2rad(SUN_AZIMUTH_DEG)
    sun_dir = np.array([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)])
    cos_to_sun = d @ sun_dir
    disc = cos_to_sun >= min(np.cos(np.deg2rad(SUN_RADIUS_DEG)), cos_to_sun.max())
    sky_on_top = float(np.sum(sky[..., 1] * solid * np.clip(up, 0.0, None)))
    sun_irradiance = SUN_FRACTION / (1.0 - SUN_FRACTION) * sky_on_top
    sun_radiance = sun_irradiance / float(np.sum(solid[disc] * np.clip(up[disc], 1e-3, None)))
    img = sky + disc[..., None] * sun_radiance
    normals = fibonacci_sphere(512)
    irradiance = np.clip(normals @ d.reshape(-1, 3).T, 0.0, None) @ (img[..., 1] * solid).reshape(-1)
    return (img * (np.pi / irradiance.max())).astype(np.float32)


def relight_envmap(height: int = 64, kind: str = "sky", seed: int = 0) -> np.ndarray:
    """An environment map (height, 2 height, 3) float32 for relighting ground truth, in the convention of
    :class:`pgc.types.Light` (latitude-longitude, +Y up). kind 'sky': bright zenith, warm sun, dark ground;
    'studio': two soft area lights on a grey background; 'low-key': one hard key light low at the side (20
    degrees up, 70 degrees round from +Z, about 15 degrees across at 1/e) over a faint fill, a key-to-fill
    irradiance ratio of about 20:1."""
    rng = np.random.default_rng(seed)
    d = envmap_directions(height, 2 * height)[0].reshape(height, 2 * height, 3)
    if kind == "sky":
        sky = np.array([0.35, 0.5, 0.8]) * np.clip(d[..., 1:2], 0, 1) ** 0.5 + np.array([0.9, 0.85, 0.8]) * 0.2
        ground = np.array([0.12, 0.1, 0.08])
        img = np.where(d[..., 1:2] > 0, sky, ground)
        sun_dir = np.array([0.5, 0.6, 0.62]) / np.linalg.norm([0.5, 0.6, 0.62])
        img = img + np.array([30.0, 27.0, 22.0]) * (d @ sun_dir > np.cos(np.deg2rad(4)))[..., None]
    elif kind == "studio":
        img = np.full(d.shape, 0.15)
        for direction, power in (([0.7, 0.4, 0.6], 6.0), ([-0.8, 0.3, 0.2], 3.0)):
            u = np.asarray(direction) / np.linalg.norm(direction)
            img = img + power * np.exp(-(1 - d @ u) / 0.02)[..., None]
        img = img * (1 + 0.02 * rng.standard_normal(img.shape[:2]))[..., None]
    elif kind == "low-key":
        img = np.full(d.shape, 0.03) * np.array([0.9, 0.95, 1.0])  # a faint cool fill
        key = np.array([np.cos(np.deg2rad(20)) * np.sin(np.deg2rad(70)), np.sin(np.deg2rad(20)),
                        np.cos(np.deg2rad(20)) * np.cos(np.deg2rad(70))])
        img = img + np.array([40.0, 37.0, 32.0]) * np.exp(-(1 - d @ key) / 0.008)[..., None]
    else:
        raise PGCDataError(f"unknown environment map kind '{kind}'; use 'sky', 'studio' or 'low-key'")
    return img.astype(np.float32)
