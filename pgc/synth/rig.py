"""The capture rig: cameras on a half dome around the person, and the lights.

A real capture dome (the paper's: 170 cameras on a half dome, 4096x2668, about 2.5-3 m from the subject,
focal lengths framing the whole person) scaled down: C cameras on rings of a hemisphere centred at the
body's mid-height, every camera looking at the body centre, the focal length chosen so the whole person
(bounding sphere of ``subject_radius``) fits each image with a margin. Cameras are OpenCV (x right, y
down, z forward), world-to-camera; world +Y is up.
"""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
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


def capture_light(radiance: tuple[float, float, float] = DEFAULT_RADIANCE) -> Light:
    """The constant environment light of the capture dome."""
    return Light(radiance=np.asarray(radiance, float))


def relight_envmap(height: int = 64, kind: str = "sky", seed: int = 0) -> np.ndarray:
    """An environment map (height, 2 height, 3) float32 for relighting ground truth, in the convention of
    :class:`pgc.types.Light` (latitude-longitude, +Y up). kind 'sky': bright zenith, warm sun, dark ground;
    'studio': two soft area lights on a grey background; 'low-key': one hard key light low at the side (20
    degrees up, 70 degrees round from +Z, about 15 degrees across at 1/e) over a faint fill, a key-to-fill
    irradiance ratio of about 20:1."""
    rng = np.random.default_rng(seed)
    theta = (np.arange(height) + 0.5) / height * np.pi  # from +Y
    phi = (np.arange(2 * height) + 0.5) / (2 * height) * 2 * np.pi
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(th) * np.sin(ph), np.cos(th), -np.sin(th) * np.cos(ph)], axis=-1)
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
