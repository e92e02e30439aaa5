"""Ground-truth fabrics: procedural base-colour textures, a weave normal map, and fibres off the surface.

Two families (docs/synth.md, "Fabrics"):

- **fibre truths** (``cotton``, ``fleece``, ``knit``, ``velvet``, ``satin``): a Lambertian cloth surface
  under a dense layer of loose fibres (:class:`HairLayer`), curves shaded by a fibre scattering model (Mitsuba's
  ``hair`` BSDF, absorption from the base colour). Their sheen comes from the fibres' geometry and
  scattering, so no BRDF the material fit can choose represents them exactly (``appearance`` 'hair-fibres').
- **in-family controls** (``*-sheen``, ``lambertian``): the surface BRDF alone (``pgc-sheen`` or
  ``lambertian``, the models the fit chooses from), with a few sparse fibres shaded by the same BRDF.

Patterns are functions of the garment's rest-pose position (metres), baked into its UV atlas, so stripes
and checks run straight across UV seams. Colours are linear RGB. BRDF parameter names are those of
:mod:`pgc.brdfs.parameters` ('pgc-sheen': roughness, sheen_color, sheen_roughness).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.embedded import embedded_points
from pgc.geometry.fibres import Fibres, HairLayer, face_frames
from pgc.types import Material, Mesh


HAIR_FIBRES = "hair-fibres"
"""The ``appearance`` of the fibre truths (ground_truth/material.json)."""


@dataclass(frozen=True)
class Fabric:
    """A fabric preset: a fibre truth (``hair`` set, over a Lambertian surface) or an in-family control."""

    name: str
    brdf: str
    params: dict = field(default_factory=dict)
    pattern: str = "solid"
    """'stripes', 'checks', 'knit', 'heather' (optionally with '+logo')."""
    colors: tuple[tuple[float, float, float], ...] = ((0.5, 0.5, 0.5),)
    weave_period: float = 0.004
    """Weave (normal map) period, metres."""
    weave_depth: float = 0.35
    """Slope amplitude of the weave bumps (0 = flat)."""
    fibre_density: float = 0.0
    """Fibres per square metre of garment (0 = none)."""
    fibre_length: float = 0.006
    fibre_radius: float = 0.0003
    hair: HairLayer | None = None
    """The fibre layer of a fibre truth (then ``brdf`` is the Lambertian surface under it)."""

    @property
    def appearance(self) -> str:
        """What renders the fabric (:func:`appearance`)."""
        return appearance(self.brdf, self.hair)


def appearance(brdf: str, hair: HairLayer | None) -> str:
    """The name of what renders a garment: 'hair-fibres' for a fibre layer (over the surface BRDF ``brdf``),
    else '<brdf> (in-family control)'."""
    return HAIR_FIBRES if hair is not None else f"{brdf} (in-family control)"


_RAD = math.pi / 180.0

FABRICS: dict[str, Fabric] = {
    # fibre truths: a Lambertian surface under fibres (cover = 2 r L density; see docs/synth.md)
    "cotton": Fabric("cotton", "lambertian", {}, "stripes+logo",
                     ((0.70, 0.69, 0.66), (0.03, 0.05, 0.16), (0.62, 0.05, 0.04)), weave_period=0.003,
                     weave_depth=0.25,
                     hair=HairLayer(density=500_000.0, length=0.004, radius=0.0001, rise=(35 * _RAD, 65 * _RAD),
                                    lie=(75 * _RAD, 88 * _RAD), longitudinal_roughness=0.35,
                                    azimuthal_roughness=0.7)),
    "fleece": Fabric("fleece", "lambertian", {}, "heather", ((0.10, 0.20, 0.11), (0.16, 0.27, 0.15)),
                     weave_period=0.005, weave_depth=0.2,
                     hair=HairLayer(density=700_000.0, length=0.007, radius=0.0001, rise=(15 * _RAD, 60 * _RAD),
                                    lie=(50 * _RAD, 88 * _RAD), longitudinal_roughness=0.3,
                                    azimuthal_roughness=0.6)),
    "knit": Fabric("knit", "lambertian", {}, "knit", ((0.28, 0.03, 0.05), (0.62, 0.50, 0.34)),
                   weave_period=0.006, weave_depth=0.5,
                   hair=HairLayer(density=600_000.0, length=0.005, radius=0.0001, rise=(30 * _RAD, 60 * _RAD),
                                  lie=(65 * _RAD, 88 * _RAD), longitudinal_roughness=0.3,
                                  azimuthal_roughness=0.6)),
    "velvet": Fabric("velvet", "lambertian", {}, "solid", ((0.22, 0.02, 0.06),), weave_depth=0.0,
                     hair=HairLayer(density=800_000.0, length=0.002, radius=0.0002, rise=(3 * _RAD, 20 * _RAD),
                                    lie=(5 * _RAD, 30 * _RAD), longitudinal_roughness=0.25,
                                    azimuthal_roughness=0.5, segments=2)),
    "satin": Fabric("satin", "lambertian", {}, "checks", ((0.04, 0.09, 0.32), (0.02, 0.20, 0.21)),
                    weave_period=0.002, weave_depth=0.1,
                    hair=HairLayer(density=600_000.0, length=0.008, radius=0.00008, rise=(70 * _RAD, 80 * _RAD),
                                   lie=(84 * _RAD, 89 * _RAD), longitudinal_roughness=0.15,
                                   azimuthal_roughness=0.3, alignment=10 * _RAD)),
    # in-family controls: the BRDFs the material fit chooses from
    "cotton-sheen": Fabric("cotton-sheen", "pgc-sheen", {"roughness": 0.9, "sheen_color": [0.06, 0.06, 0.06],
                                                        "sheen_roughness": 0.6},
                           "stripes+logo", ((0.70, 0.69, 0.66), (0.03, 0.05, 0.16), (0.62, 0.05, 0.04)),
                           weave_period=0.003, weave_depth=0.25),
    "fleece-sheen": Fabric("fleece-sheen", "pgc-sheen", {"roughness": 0.8, "sheen_color": [0.35, 0.36, 0.35],
                                                        "sheen_roughness": 0.45},
                           "heather", ((0.10, 0.20, 0.11), (0.16, 0.27, 0.15)), weave_period=0.005,
                           weave_depth=0.2, fibre_density=2500.0, fibre_length=0.007, fibre_radius=0.0004),
    "knit-sheen": Fabric("knit-sheen", "pgc-sheen", {"roughness": 0.85, "sheen_color": [0.25, 0.22, 0.2],
                                                    "sheen_roughness": 0.35},
                         "knit", ((0.28, 0.03, 0.05), (0.62, 0.50, 0.34)), weave_period=0.006, weave_depth=0.5,
                         fibre_density=1200.0, fibre_length=0.005, fibre_radius=0.0003),
    "rib-knit-sheen": Fabric("rib-knit-sheen", "pgc-sheen", {"roughness": 0.85, "sheen_color": [0.22, 0.2, 0.18],
                                                            "sheen_roughness": 0.4},
                             "heather", ((0.50, 0.40, 0.29), (0.60, 0.50, 0.37)), weave_period=0.004,
                             weave_depth=0.3, fibre_density=1200.0, fibre_length=0.006, fibre_radius=0.0003),
    "satin-sheen": Fabric("satin-sheen", "pgc-sheen", {"roughness": 0.4, "sheen_color": [0.85, 0.83, 0.78],
                                                      "sheen_roughness": 0.22},
                          "checks", ((0.04, 0.09, 0.32), (0.02, 0.20, 0.21)), weave_period=0.002, weave_depth=0.1),
    "lambertian": Fabric("lambertian", "lambertian", {}, "checks", ((0.60, 0.26, 0.05), (0.60, 0.60, 0.58)),
                         weave_depth=0.0),
}
"""The fabric presets by name."""


def get_fabric(name: str) -> Fabric:
    if name not in FABRICS:
        raise PGCDataError(f"unknown fabric '{name}'; fabrics: {', '.join(FABRICS)}")
    return FABRICS[name]


# ----------------------------------------------------------------------------------------------- atlas


def texel_positions(mesh: Mesh, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Rest positions at the texel centres of the UV atlas: (size, size, 3) and a (size, size) bool
    coverage; uncovered texels take the position of the nearest covered texel (seam padding)."""
    from scipy.ndimage import distance_transform_edt

    from pgc.texture.atlas import texel_geometry

    if mesh.uv is None:
        raise PGCDataError(f"mesh '{mesh.name}' has no UVs; the fabric textures need a UV atlas")
    geom = texel_geometry(mesh, size, size)
    covered = geom.valid
    _, (ny, nx) = distance_transform_edt(~covered, return_indices=True)
    return geom.position[ny, nx], covered


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """0 below ``e0``, 1 above ``e1``, the cubic 3t^2 - 2t^3 of t = (x - e0) / (e1 - e0) between."""
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def value_noise(p: np.ndarray, cell: float, seed: int) -> np.ndarray:
    """Smooth 3D value noise in [0, 1] with lattice spacing ``cell`` metres (deterministic per seed)."""
    q = p / cell
    i = np.floor(q).astype(np.int64)
    f = q - i
    f = f * f * (3 - 2 * f)
    out = np.zeros(p.shape[:-1])
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                h = (i[..., 0] + dx) * 73856093 ^ (i[..., 1] + dy) * 19349663 ^ (i[..., 2] + dz) * 83492791 ^ seed
                r = ((h * 2654435761) % 4294967296) / 4294967296.0
                w = ((f[..., 0] if dx else 1 - f[..., 0]) * (f[..., 1] if dy else 1 - f[..., 1])
                     * (f[..., 2] if dz else 1 - f[..., 2]))
                out += w * r
    return out


def _logo_mask(p: np.ndarray, center: tuple[float, float], width: float) -> np.ndarray:
    """Coverage of the text 'PGC' in a ring, printed on the front (+z) of the garment around ``center``."""
    import cv2

    res = 256
    img = np.zeros((res, res), np.uint8)
    cv2.circle(img, (res // 2, res // 2), int(res * 0.45), 255, thickness=int(res * 0.06), lineType=cv2.LINE_AA)
    cv2.putText(img, "PGC", (int(res * 0.14), int(res * 0.63)), cv2.FONT_HERSHEY_DUPLEX, res / 110, 255,
                thickness=max(1, res // 40), lineType=cv2.LINE_AA)
    u = ((p[..., 0] - center[0]) / width + 0.5) * res
    v = (0.5 - (p[..., 1] - center[1]) / width) * res
    ok = (u >= 0) & (u < res - 1) & (v >= 0) & (v < res - 1) & (p[..., 2] > 0)
    out = np.zeros(p.shape[:-1])
    ui, vi = u[ok].astype(int), v[ok].astype(int)
    out[ok] = img[vi, ui] / 255.0
    return out


def base_color(fabric: Fabric, positions: np.ndarray, texel_size: float, seed: int,
               logo_center: tuple[float, float] = (0.0, 1.2)) -> np.ndarray:
    """The fabric's base colour (..., 3) at rest ``positions`` (..., 3); ``texel_size`` (metres) sets the
    anti-aliasing width of pattern edges."""
    c = [np.asarray(x, np.float64) for x in fabric.colors]
    x, y, z = positions[..., 0], positions[..., 1], positions[..., 2]
    aa = max(texel_size, 1e-4)
    kind = fabric.pattern.split("+")[0]
    if kind == "stripes":
        s = np.abs(np.mod(y / 0.05, 1.0) - 0.5) * 0.05  # distance to the stripe centre line, metres
        t = smoothstep(0.0125 - aa, 0.0125 + aa, s)
        rgb = c[0] * (1 - t[..., None]) + c[1] * t[..., None]
    elif kind == "checks":
        angle = np.arctan2(x, z) * 0.16  # around the body, metres at ~16 cm radius
        sx = smoothstep(-aa, aa, np.sin(2 * np.pi * angle / 0.06) * 0.01)
        sy = smoothstep(-aa, aa, np.sin(2 * np.pi * y / 0.06) * 0.01)
        t = (0.5 * sx + 0.5 * sy)[..., None]
        rgb = c[0] * (1 - t) + c[1] * t
    elif kind == "knit":
        angle = np.arctan2(x, z) * 0.16
        chevron = np.mod((y + np.abs(np.mod(angle / 0.03, 1.0) - 0.5) * 0.03) / 0.04, 1.0)
        t = smoothstep(0.5 - aa / 0.04, 0.5 + aa / 0.04, np.abs(chevron - 0.5) * 2)[..., None]
        rgb = c[0] * (1 - t) + c[1] * t
        rgb *= (0.85 + 0.3 * value_noise(positions, 0.004, seed))[..., None]
    elif kind == "heather":
        n = value_noise(positions, 0.01, seed) * 0.6 + value_noise(positions, 0.003, seed + 1) * 0.4
        rgb = c[0] + (c[1] - c[0]) * n[..., None]
    elif kind == "solid":
        rgb = np.broadcast_to(c[0], positions.shape).copy()
    else:
        raise PGCDataError(f"fabric '{fabric.name}': unknown pattern '{fabric.pattern}'")
    if fabric.pattern.endswith("+logo"):
        logo = _logo_mask(positions, logo_center, 0.16)[..., None]
        rgb = rgb * (1 - logo) + c[2] * logo
    return np.clip(rgb, 0.0, 1.0).astype(np.float32)


def weave_normal_map(fabric: Fabric, size: int, texel_size: float) -> np.ndarray | None:
    """Tangent-space normal map (size, size, 3), encoded (n + 1) / 2, of a plain weave (over-under bumps
    with period ``weave_period``); None when the fabric is flat or the atlas cannot resolve the weave."""
    period_px = fabric.weave_period / texel_size
    if fabric.weave_depth <= 0 or period_px < 2.5:
        period_px = 2.5 if fabric.weave_depth > 0 else 0.0
    if period_px == 0.0:
        return None
    ys, xs = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
    w = 2 * np.pi / period_px
    # height h = A (sin(w x) cos(w y / 2) + cos(w y) sin(w x / 2)): threads crossing over and under
    a = fabric.weave_depth / w
    dhdx = a * (w * np.cos(w * xs) * np.cos(w * ys / 2) + 0.5 * w * np.cos(w * ys) * np.cos(w * xs / 2))
    dhdy = a * (-0.5 * w * np.sin(w * xs) * np.sin(w * ys / 2) - w * np.sin(w * ys) * np.sin(w * xs / 2))
    n = np.stack([-dhdx, dhdy, np.ones_like(xs)], axis=-1)  # image y points down, texture v up
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n + 1) / 2).astype(np.float32)


def texel_size(mesh: Mesh, size: int) -> float:
    """Mean edge of one texel on the surface, metres (surface area over covered UV area)."""
    uv = mesh.uv[mesh.face_uv].astype(np.float64) * size
    a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    uv_area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()
    return float(np.sqrt(mesh.face_areas().sum() / max(uv_area, 1e-12)))


def make_material(fabric: Fabric, garment: Mesh, size: int, seed: int) -> tuple[Material, np.ndarray | None]:
    """The ground-truth Material (base colour baked over ``garment``'s atlas, ``size`` texels square) and the
    weave normal map (or None)."""
    positions, _ = texel_positions(garment, size)
    ts = texel_size(garment, size)
    chest = garment.vertices[:, 1].min() * 0.3 + garment.vertices[:, 1].max() * 0.7
    tex = base_color(fabric, positions, ts, seed, logo_center=(0.0, float(chest)))
    material = Material(fabric.brdf, {k: (list(v) if isinstance(v, (list, tuple)) else float(v))
                                      for k, v in fabric.params.items()}, tex)
    return material, weave_normal_map(fabric, size, ts)


# ---------------------------------------------------------------------------------------------- fibres


def _roots(garment: Mesh, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points uniform over ``garment``'s area: face indices (N,) and barycentrics (N, 3)."""
    areas = garment.face_areas()
    face = rng.choice(len(areas), size=count, p=areas / areas.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    return face, np.stack([1 - s, s * (1 - r2), s * r2], axis=1)


def _directions(tilt: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors (..., 3) in a face frame at angle ``tilt`` from the normal and azimuth ``phi``."""
    return np.stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)], axis=-1)


def make_fibres(fabric: Fabric, garment: Mesh, material: Material, seed: int, scale: float = 1.0) -> Fibres | None:
    """Fibres of ``fabric`` scattered uniformly over ``garment`` (``scale`` multiplies the density);
    None for fabrics without fibres. A fibre truth's layer follows :class:`HairLayer`; a control's sparse
    fibres leave the surface steeply and curl over."""
    if fabric.hair is not None:
        return _hair_fibres(fabric, garment, material, seed, scale)
    count = int(round(fabric.fibre_density * scale * garment.face_areas().sum()))
    if count == 0:
        return None
    rng = np.random.default_rng(seed)
    face, bary = _roots(garment, count, rng)
    phi = rng.uniform(0, 2 * np.pi, count)
    tilt = np.stack([rng.uniform(0.3, 0.7, count), rng.uniform(0.9, 1.4, count)], axis=1)  # rad from normal
    direction = _directions(tilt, phi[:, None])
    color = np.asarray(material.base_color, np.float64).reshape(-1, 3).mean(axis=0) * 1.1
    return Fibres(face, bary, direction, fabric.fibre_length, fabric.fibre_radius, np.clip(color, 0, 1))


def _hair_fibres(fabric: Fabric, garment: Mesh, material: Material, seed: int, scale: float) -> Fibres | None:
    """The fibre layer of a fibre truth: roots, directions (float32) and colours grouped by the nearest of the
    fabric's colours (one scattering model per group)."""
    from pgc.texture.sample import sample_uv

    layer = fabric.hair
    count = int(round(layer.density * scale * garment.face_areas().sum()))
    if count == 0:
        return None
    rng = np.random.default_rng(seed)
    face, bary = _roots(garment, count, rng)
    if layer.alignment > 0:
        warp = face_frames(garment.vertices, garment.faces, face) @ np.array([0.0, -1.0, 0.0])
        phi = (np.arctan2(warp[:, 1], warp[:, 0]) + rng.normal(0.0, layer.alignment, count)
               + np.pi * (rng.random(count) < 0.5))
        wander = np.zeros((count, layer.segments))
    else:
        phi = rng.uniform(0, 2 * np.pi, count)
        wander = np.cumsum(rng.normal(0.0, 0.15, (count, layer.segments)), axis=1)  # a slight curl
    tilt = np.empty((count, layer.segments))
    tilt[:, 0] = rng.uniform(*layer.rise, count)
    tilt[:, 1:] = rng.uniform(*layer.lie, count)[:, None] + rng.normal(0.0, 0.03, (count, layer.segments - 1))
    direction = _directions(np.clip(tilt, 0.0, 0.5 * np.pi), phi[:, None] + wander).astype(np.float32)
    if material.base_color is not None:
        uv = np.einsum("nk,nkd->nd", bary, np.asarray(garment.uv, np.float64)[garment.face_uv[face]])
        rgb = sample_uv(np.asarray(material.base_color, np.float64), uv)
    else:
        rgb = np.broadcast_to(np.asarray(material.params["base_color"], np.float64), (count, 3))
    palette = np.asarray(fabric.colors, np.float64)
    group = np.argmin(((rgb[:, None] - palette[None]) ** 2).sum(axis=-1), axis=1)
    used = np.unique(group)
    group = np.searchsorted(used, group)
    palette = np.stack([rgb[group == g].mean(axis=0) for g in range(len(used))])
    color = np.bincount(group, minlength=len(used)) @ palette / count
    return Fibres(face.astype(np.int32), bary.astype(np.float32), direction, layer.length, layer.radius,
                  np.clip(color, 0, 1), hair=layer, group=group.astype(np.int32),
                  palette=np.clip(palette, 0, 1).astype(np.float32))
