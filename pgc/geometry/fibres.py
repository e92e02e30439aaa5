"""Fibres rooted on a garment's faces (:class:`Fibres`, they follow any deformation of the garment) and the
fibre scattering layer a fibre truth gives them (:class:`HairLayer`, Mitsuba's ``hair`` model). A scene
renderer's input (:class:`pgc.roles.scene_renderer.SceneGeometry`): the generator (:mod:`pgc.synth`) makes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgc.geometry.embedded import embedded_points


@dataclass(frozen=True)
class HairLayer:
    """A layer of loose fibres over the cloth surface, shaded by Mitsuba's ``hair`` BSDF (the fibre model of
    Chiang et al. 2016: R, TT, TRT lobes of a dielectric cylinder with absorbing interior).

    A fibre is a polyline of ``segments`` equal segments rooted on the surface: the first leaves at an angle
    from the surface normal drawn from ``rise``, the others lie at angles drawn from ``lie`` (radians; pi/2
    is in the surface plane). Its azimuth around the normal is uniform, or, with ``alignment`` > 0, normally
    spread by that many radians around the garment's warp (the rest-pose vertical, either way along it).
    The fibres' strands are effective: one curve stands for a bundle of real fibres (5-15 um radius), so the
    cover (projected fibre area per surface area) is what matters optically, and ``density`` sets it."""

    density: float
    """Fibres per square metre of garment."""
    length: float
    """Fibre length, metres."""
    radius: float
    """Fibre radius, metres."""
    rise: tuple[float, float]
    lie: tuple[float, float]
    longitudinal_roughness: float
    """Mitsuba ``hair`` beta_m: the width of the highlights along the fibre."""
    azimuthal_roughness: float
    """Mitsuba ``hair`` beta_n: the width around the fibre; it also sets the colour -> absorption mapping."""
    alignment: float = 0.0
    """0: random azimuth; > 0: standard deviation (radians) of the azimuth around the warp direction."""
    eta: float = 1.55
    """Refractive index of the fibre (cotton, wool, polyester: 1.53-1.58)."""
    scale_tilt: float = 2.0
    """Tilt of the fibre's surface scales, degrees (shifts the R and TRT highlights)."""
    segments: int = 3

    def cover(self) -> float:
        """Projected area of the fibres per unit garment area seen side-on (2 r L density)."""
        return 2.0 * self.radius * self.length * self.density

    def record(self) -> dict:
        """The layer's parameters for ground_truth/material.json (SI units, angles in radians)."""
        return {"density_per_m2": self.density, "length_m": self.length, "radius_m": self.radius,
                "rise_rad": list(self.rise), "lie_rad": list(self.lie), "alignment_rad": self.alignment,
                "longitudinal_roughness": self.longitudinal_roughness,
                "azimuthal_roughness": self.azimuthal_roughness, "eta": self.eta,
                "scale_tilt_deg": self.scale_tilt, "segments": self.segments, "cover": self.cover()}

    @classmethod
    def from_record(cls, record: dict) -> HairLayer:
        """The layer of a :meth:`record` (as read back from material.json)."""
        return cls(float(record["density_per_m2"]), float(record["length_m"]), float(record["radius_m"]),
                   tuple(record["rise_rad"]), tuple(record["lie_rad"]), float(record["longitudinal_roughness"]),
                   float(record["azimuthal_roughness"]), float(record["alignment_rad"]), float(record["eta"]),
                   float(record["scale_tilt_deg"]), int(record["segments"]))


def hair_absorption(color: np.ndarray, azimuthal_roughness: float) -> np.ndarray:
    """Absorption coefficient sigma_a (per fibre radius, RGB) that gives a fibre assembly the colour ``color``
    (linear RGB in (0, 1]): the inversion of Chiang et al. 2016, eq. 9 (a quintic in beta_n)."""
    b = float(azimuthal_roughness)
    denom = 5.969 - 0.215 * b + 2.532 * b ** 2 - 10.73 * b ** 3 + 5.574 * b ** 4 + 0.245 * b ** 5
    return (np.log(np.clip(np.asarray(color, np.float64), 1e-4, 1.0)) / denom) ** 2


def face_frames(vertices: np.ndarray, faces: np.ndarray, face: np.ndarray) -> np.ndarray:
    """(N, 3, 3) orthonormal frames of faces ``face``, rows (tangent along the first edge, bitangent, normal)."""
    v = np.asarray(vertices, np.float64)[faces[face]]
    e1 = v[:, 1] - v[:, 0]
    n = np.cross(e1, v[:, 2] - v[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
    t = e1 / np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-20)
    return np.stack([t, np.cross(n, t), n], axis=1)


@dataclass
class Fibres:
    """Fibres rooted on garment faces; they follow any deformation of the garment."""

    face: np.ndarray
    """(N,) root face index."""
    bary: np.ndarray
    """(N, 3) barycentric root position."""
    direction: np.ndarray
    """(N, K - 1, 3) segment directions in the local (tangent, bitangent, normal) frame of the face."""
    length: float
    radius: float
    color: np.ndarray
    """(3,) linear RGB mean colour of the fibres (the albedo layer of fibre hits)."""
    offset: np.ndarray | None = None
    """(N,) root offset along the interpolated garment normal, metres (roots on a detail relief)."""
    hair: HairLayer | None = None
    """The fibre scattering model (fibre truths); None: the fibres are shaded by the garment's BRDF."""
    group: np.ndarray | None = None
    """(N,) index into ``palette``: the colour of each fibre (fibre truths)."""
    palette: np.ndarray | None = None
    """(G, 3) linear RGB fibre colours (fibre truths): the base colour around the roots, grouped."""

    def control_points(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(N, K, 3) polyline control points on a garment with ``vertices`` (its rest or a deformed pose)."""
        root = embedded_points(vertices, faces, self.face, self.bary, self.offset)
        frame = face_frames(vertices, faces, self.face)
        steps = np.einsum("nsk,nkd->nsd", self.direction, frame) * (self.length / self.direction.shape[1])
        return np.concatenate([root[:, None], root[:, None] + np.cumsum(steps, axis=1)], axis=1)
