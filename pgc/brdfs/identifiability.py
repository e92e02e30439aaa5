"""Which ``pgc-sheen`` parameters a capture's lighting identifies: the Jacobian of rendered pixels.

The study scene is a convex patch (points of a unit sphere, so no shadowing) seen by a ring of distant
cameras; a "pixel" is one (point, view) pair whose view cosine is at least ``min_view_cos`` (the fit's
interior mask drops the grazing silhouette). Each point carries a base colour from a palette (the fabric's
texture colours, dealt out in stripes). A capture is one or more *frames*, each a set of distant light
directions with known relative RGB radiance (a uniform environment, a sky with a sun, a key light); the
unknown light is one RGB scale ``light`` common to all frames (the fit's constant light radiance), so
``pixel_c = light_c sum_k f_cos(l_k, v) E_k,c`` with the BRDF of :mod:`pgc.brdfs.maths` and the base colour
times ``base_scale`` (fixed at 1 in the material fit: the base-colour texture is given).

Parameters are taken relative (the Jacobian's columns are ``p dI/dp``), so a singular value is the RMS pixel
change, per pixel, for a unit relative change along its direction; the covariance for pixel noise ``s``
over ``n`` pixels is ``s^2 / n (J^T J / n)^-1`` (relative standard errors). float64 throughout (torch).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pgc.brdfs.maths import eval_pgc_sheen, tangent_frame
from pgc.least_squares import levenberg_marquardt
from pgc.sampling import envmap_directions, fibonacci_sphere

PARAMETER_NAMES = ("base_r", "base_g", "base_b", "light_r", "light_g", "light_b", "roughness",
                   "sheen_r", "sheen_g", "sheen_b", "sheen_roughness")
"""The study's parameters, in vector order."""
FIT_PARAMETERS = PARAMETER_NAMES[3:]
"""Those the material fit optimises (the base-colour texture is given)."""


@dataclass
class Frame:
    """One lighting condition: distant light directions (K, 3), world frame (+Y up), and the known RGB
    irradiance each contributes (K, 3): radiance times solid angle for an environment cell."""

    directions: np.ndarray
    irradiance: np.ndarray
    name: str = ""


@dataclass
class StudyScene:
    """Surface points (normals = positions on the unit sphere), their base colours and the view directions."""

    normals: np.ndarray
    base: np.ndarray
    views: np.ndarray
    min_view_cos: float = 0.2
    pairs: tuple[np.ndarray, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        cos = self.normals @ self.views.T
        point, view = np.nonzero(cos >= self.min_view_cos)
        self.pairs = (point, view)


def direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector at ``elevation_deg`` above the horizon (+Y up) and ``azimuth_deg`` from +Z toward +X."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])


def study_scene(palette: tuple[tuple[float, float, float], ...], n_points: int = 300, n_views: int = 12,
                min_view_cos: float = 0.2) -> StudyScene:
    """Points on the upper 3/4 of a sphere (a garment's normals rarely face straight down), base colours
    from ``palette`` in 8 longitudinal stripes, and a camera ring: ``n_views`` directions alternating between
    elevations 0 and 30 degrees (like the synthetic capture's rig)."""
    normals = fibonacci_sphere(n_points)
    normals = normals[normals[:, 1] > -0.5]
    stripe = ((np.arctan2(normals[:, 0], normals[:, 2]) + math.pi) / (2 * math.pi) * 8).astype(int) % len(palette)
    base = np.asarray(palette, np.float64)[stripe]
    views = np.stack([direction(30.0 * (i % 2), 360.0 * i / n_views) for i in range(n_views)])
    return StudyScene(normals, base, views, min_view_cos)


def uniform_frame(n_dirs: int = 400) -> Frame:
    """A uniform environment of radiance 1: each Fibonacci direction carries solid angle 4 pi / n."""
    d = fibonacci_sphere(n_dirs)
    return Frame(d, np.full((n_dirs, 3), 4 * math.pi / n_dirs), "uniform")


def sky_sun_frame(n_dirs: int = 400, sun_elevation_deg: float = 40.0, sun_azimuth_deg: float = 30.0,
                  sun_fraction: float = 0.6) -> Frame:
    """A sky (radiance 0.2 below the horizon, rising to 1 at the zenith, bluish) plus a sun carrying
    ``sun_fraction`` of the total irradiance on an upward-facing point."""
    d = fibonacci_sphere(n_dirs)
    up = np.clip(d[:, 1], 0.0, 1.0)
    sky = (0.2 + 0.8 * up)[:, None] * np.array([0.8, 0.9, 1.1])[None] * (4 * math.pi / n_dirs)
    sky_on_top = float(np.sum(sky[:, 1] * np.clip(d[:, 1], 0.0, None)))
    sun_dir = direction(sun_elevation_deg, sun_azimuth_deg)
    sun = sun_fraction / (1.0 - sun_fraction) * sky_on_top / max(sun_dir[1], 1e-3)
    return Frame(np.concatenate([d, sun_dir[None]]), np.concatenate([sky, np.full((1, 3), sun)]), "sky+sun")


def key_light_frames(elevations_azimuths: tuple[tuple[float, float], ...] = ((20.0, 0.0), (20.0, 120.0),
                                                                           (20.0, 240.0), (60.0, 60.0)),
                     irradiance: float = math.pi) -> list[Frame]:
    """One frame per known directional key light (irradiance ``irradiance``: pi gives a white Lambertian
    surface facing it radiance 1, as the uniform environment does)."""
    return [Frame(direction(e, a)[None], np.full((1, 3), irradiance), f"key {e:g}/{a:g}")
            for e, a in elevations_azimuths]


def envmap_frame(envmap: np.ndarray, rotation_deg: float = 0.0, name: str = "envmap") -> Frame:
    """An environment map (H, 2H, 3; :class:`pgc.types.Light` convention, rotated ``rotation_deg`` about +Y) as
    a frame: one direction per pixel, irradiance = radiance x the pixel's solid angle."""
    env = np.asarray(envmap, np.float64)
    directions, solid = envmap_directions(env.shape[0], env.shape[1], rotation_deg)
    return Frame(directions, env.reshape(-1, 3) * solid[:, None], name)


def lightings(n_dirs: int = 400) -> dict[str, list[Frame]]:
    """The compared captures: (a) uniform environment, (b) sky + sun, (c) uniform plus four key-light frames."""
    return {"uniform": [uniform_frame(n_dirs)], "sky+sun": [sky_sun_frame(n_dirs)],
            "uniform+4 keys": [uniform_frame(n_dirs), *key_light_frames()]}


def parameter_vector(base_scale: Any, light: Any, roughness: float, sheen_color: Any,
                     sheen_roughness: float) -> np.ndarray:
    """The 11 study parameters (order :data:`PARAMETER_NAMES`) as a float64 vector."""
    return np.concatenate([np.asarray(base_scale, np.float64).reshape(3), np.asarray(light, np.float64).reshape(3),
                           [roughness], np.asarray(sheen_color, np.float64).reshape(3), [sheen_roughness]])


def render(scene: StudyScene, frames: list[Frame], theta: Any) -> Any:
    """The pixels (n_frames * n_pairs * 3,) for parameter vector ``theta`` (torch float64 tensor, order
    :data:`PARAMETER_NAMES`), differentiable in ``theta``."""
    import torch

    from pgc.arrays import array_ops

    ops = array_ops("torch")
    point, view = scene.pairs
    n = torch.as_tensor(scene.normals[point], dtype=torch.float64)
    v = torch.as_tensor(scene.views[view], dtype=torch.float64)
    t, b = tangent_frame(ops, n)
    v_loc = torch.stack([(v * t).sum(-1), (v * b).sum(-1), (v * n).sum(-1)], -1)
    base = torch.as_tensor(scene.base[point], dtype=torch.float64) * theta[0:3]
    params = {"roughness": theta[6], "sheen_color": theta[7:10], "sheen_roughness": theta[10]}
    out = []
    for frame in frames:
        dirs = torch.as_tensor(frame.directions, dtype=torch.float64)
        l_loc = torch.stack([t @ dirs.T, b @ dirs.T, n @ dirs.T], -1)  # (p, k, 3)
        f_cos = eval_pgc_sheen(ops, l_loc, v_loc[:, None, :], base[:, None, :], params)
        irr = torch.as_tensor(frame.irradiance, dtype=torch.float64)
        out.append((f_cos * irr[None]).sum(1) * theta[3:6])
    return torch.cat(out).reshape(-1)


def jacobian(scene: StudyScene, frames: list[Frame], theta: np.ndarray) -> np.ndarray:
    """d pixels / d theta (n_pixels, 11), by torch forward-mode autodiff in float64 (one pass per parameter)."""
    import torch
    import torch.autograd.forward_ad as fwAD

    t = torch.as_tensor(np.asarray(theta, np.float64))
    columns = []
    with torch.no_grad(), fwAD.dual_level():
        for i in range(len(t)):
            tangent = torch.zeros_like(t)
            tangent[i] = 1.0
            columns.append(fwAD.unpack_dual(render(scene, frames, fwAD.make_dual(t, tangent))).tangent)
    return torch.stack(columns, 1).numpy()


@dataclass
class Identifiability:
    """The conditioning of the relative Jacobian over a subset of parameters."""

    names: tuple[str, ...]
    singular_values: np.ndarray
    """RMS pixel change per unit relative change along each right singular vector, descending."""
    null_direction: np.ndarray
    """The right singular vector of the smallest singular value (unit, loadings per parameter)."""
    relative_std: np.ndarray
    """Relative standard error of each parameter for pixel noise ``noise`` over the scene's pixels (inf
    where the information matrix is singular)."""
    n_pixels: int

    @property
    def condition(self) -> float:
        return float(self.singular_values[0] / max(self.singular_values[-1], 1e-300))


def analyse(J: np.ndarray, theta: np.ndarray, names: tuple[str, ...], noise: float) -> Identifiability:
    """Singular values, weakest direction and relative standard errors of the parameters ``names`` (the
    other columns are held fixed) for Jacobian ``J`` at ``theta`` and pixel noise ``noise`` (std)."""
    cols = [PARAMETER_NAMES.index(n) for n in names]
    n_pix = J.shape[0]
    Jr = J[:, cols] * theta[cols][None] / math.sqrt(n_pix)
    _, s, vt = np.linalg.svd(Jr, full_matrices=False)
    null = vt[-1] * (1.0 if vt[-1][np.argmax(np.abs(vt[-1]))] > 0 else -1.0)
    with np.errstate(divide="ignore"):
        inv_s2 = np.where(s > s[0] * 1e-13, 1.0 / s ** 2, np.inf)
    variance = (vt.T ** 2 * np.where(np.isinf(inv_s2), 0.0, inv_s2)[None]).sum(1)
    variance = np.where((np.abs(vt.T[:, np.isinf(inv_s2)]) > 1e-6).any(1), np.inf, variance)
    return Identifiability(tuple(names), s, null, noise * np.sqrt(variance / n_pix), n_pix)


def recover(scene: StudyScene, frames: list[Frame], truth: np.ndarray, start: np.ndarray, noise: float,
            seed: int = 0, iterations: int = 30) -> np.ndarray:
    """Fit :data:`FIT_PARAMETERS` (base scale fixed at ``truth``'s) to the pixels of ``truth`` plus Gaussian
    noise of std ``noise``, from ``start``, by Levenberg-Marquardt on the log parameters (roughness, sheen
    colour and sheen roughness clamped to their upper bound 1); returns the fitted 11-vector."""
    import torch

    cols = np.array([PARAMETER_NAMES.index(n) for n in FIT_PARAMETERS])
    bounded = np.array([n != "light" and not n.startswith("light_") for n in FIT_PARAMETERS])
    lowest = np.where(np.array(FIT_PARAMETERS) == "sheen_roughness", math.log(0.01), -np.inf)
    rng = np.random.default_rng(seed)
    target = render(scene, frames, torch.as_tensor(truth)).numpy()
    target = target + rng.normal(0.0, noise, target.shape)
    theta = np.asarray(start, np.float64).copy()
    theta[:3] = truth[:3]

    def parameters(log_p: np.ndarray) -> np.ndarray:
        t = theta.copy()
        t[cols] = np.exp(log_p)
        return t

    def residual(log_p: np.ndarray) -> np.ndarray:
        return render(scene, frames, torch.as_tensor(parameters(log_p))).numpy() - target

    def log_jacobian(log_p: np.ndarray, r: np.ndarray) -> np.ndarray:
        t = parameters(log_p)
        return jacobian(scene, frames, t)[:, cols] * t[cols][None]  # d pixels / d log p

    def project(log_p: np.ndarray) -> np.ndarray:
        return np.maximum(np.where(bounded, np.minimum(log_p, 0.0), log_p), lowest)

    return parameters(levenberg_marquardt(residual, log_jacobian, np.log(theta[cols]), project, iterations).x)
