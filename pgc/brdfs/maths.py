"""The cloth BRDF maths, written once over the array-operations layer (:class:`pgc.arrays.ArrayOps`).

Conventions: directions are unit vectors in the local shading frame (z = normal). ``L`` points toward the
light, ``V`` toward the viewer. Every ``eval_*`` returns ``f(L, V) * max(cos theta_L, 0)`` as a linear RGB
colour, and zero when either direction is at or below the horizon.

Models
- Lambertian: ``f = sigma_d / pi``.
- Disney (Burley 2012), diffuse + sheen, specular/metallic/clearcoat = 0:
  ``f = sigma_d / pi (1 + (F_D90 - 1) F(L)) (1 + (F_D90 - 1) F(V)) + sheen C_sheen F(cos d)`` with
  ``F(c) = (1 - c)^5``, ``F_D90 = 0.5 + 2 roughness cos^2 d``, ``cos d = L.H`` (H the half vector),
  ``C_sheen = lerp(1, sigma_d / lum(sigma_d), sheen_tint)``. Identical to Mitsuba's ``principled`` with
  specular, metallic, clearcoat, spec_trans at 0 (tested).
- PGC sheen (the paper's Eq. 1): ``f cos = sigma_s R(x, y) D_LTC(L) + (1 - R(x, y)) sigma_d f_diffuse cos``
  with the Zeltner et al. 2022 microfiber sheen as a linearly transformed cosine, ``x = cos theta_V``,
  ``y = sheen_roughness`` clamped to [0.01, 1], R its directional albedo (closed-form fits).

``cos^2 d`` is computed as ``(1 + L.V) / 2`` (no half vector to normalise, defined for L = -V).
"""

from __future__ import annotations

import math
from typing import Any

from pgc.arrays import ArrayOps

INV_PI = 1.0 / math.pi
SHEEN_ROUGHNESS_MIN = 0.01
"""The LTC fits are valid for sheen roughness in [0.01, 1]; inputs are clamped to it."""
_EPS_AZIMUTH = 1e-14
"""Below this squared in-plane length of V, V is taken parallel to N (the LTC frame's X is then arbitrary:
the lobe is rotationally symmetric there because bInv(x = 1) = 0)."""


def schlick_weight(ops: ArrayOps, c: Any) -> Any:
    """``(1 - c)^5`` for c clamped to [0, 1]."""
    t = 1.0 - ops.clip(c, 0.0, 1.0)
    t2 = t * t
    return t2 * t2 * t


def ltc_coefficients(ops: ArrayOps, x: Any, y: Any) -> tuple[Any, Any]:
    """Zeltner et al. 2022 fitted inverse-LTC entries (aInv, bInv) at ``x = cos theta_V``, roughness ``y``.

    ``x`` is clamped to [0, 1] and ``y`` to [0.01, 1].
    """
    x = ops.clip(x, 0.0, 1.0)
    y = ops.clip(y, SHEEN_ROUGHNESS_MIN, 1.0)
    a_inv = (2.58126 * x + 0.813703 * y) * y / (1.0 + 0.310327 * x * x + 2.60994 * x * y)
    # sqrt(1 - x) with a floor: its derivative is infinite at x = 1 (V along N); the floor changes bInv by
    # at most 1e-6 * |(y - 1) y^3 / den| there.
    sqrt_1mx = ops.sqrt(ops.maximum(1.0 - x, 1e-12))
    b_inv = sqrt_1mx * (y - 1.0) * y * y * y / (0.0000254053 + 1.71228 * x - 1.71506 * x * y + 1.34174 * y * y)
    return a_inv, b_inv


def sheen_albedo(ops: ArrayOps, x: Any, y: Any) -> Any:
    """Directional albedo R(x, y) of the Zeltner sheen lobe (fitted Gaussian plus offset), in [0, 1]."""
    x = ops.clip(x, 0.0, 1.0)
    y = ops.clip(y, SHEEN_ROUGHNESS_MIN, 1.0)
    s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y))
    m = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y * y))) / (0.046391 + y)
    o = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y))
    z = (x - m) / s
    return ops.clip(ops.exp(-0.5 * z * z) / (s * math.sqrt(2.0 * math.pi)) + o, 0.0, 1.0)


def sheen_frame(ops: ArrayOps, vx: Any, vy: Any) -> tuple[Any, Any]:
    """In-plane unit axis X = normalize(V - N (N.V)) as (Xx, Xy); (1, 0) when V is parallel to N."""
    r2 = vx * vx + vy * vy
    ok = r2 > _EPS_AZIMUTH
    inv_r = 1.0 / ops.sqrt(ops.maximum(r2, _EPS_AZIMUTH))
    return ops.where(ok, vx * inv_r, 1.0), ops.where(ok, vy * inv_r, 0.0)


def tangent_frame(ops: ArrayOps, n: Any) -> tuple[Any, Any]:
    """Orthonormal tangents (t, b) completing unit normals n (..., 3) to a right-handed frame (t, b, n),
    branchless (Duff et al. 2017)."""
    nx, ny, nz = ops.split(n)
    sign = ops.where(nz >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b_ = nx * ny * a
    t = ops.stack([1.0 + sign * nx * nx * a, sign * b_, -sign * nx], -1)
    b = ops.stack([b_, sign + ny * ny * a, -ny], -1)
    return t, b


def ltc_density(ops: ArrayOps, a_inv: Any, b_inv: Any, wx: Any, wy: Any, wz: Any) -> Any:
    """The cosine-weighted LTC lobe D(w) for w in the LTC frame (X, Y, N); a pdf over the hemisphere.

    ``wo = (aInv w.x + bInv w.z, aInv w.y, w.z)``, ``D = max(wo.z, 0) / pi (aInv / |wo|^2)^2``.
    """
    ox = a_inv * wx + b_inv * wz
    oy = a_inv * wy
    len2 = ops.maximum(ox * ox + oy * oy + wz * wz, 1e-30)
    k = a_inv / len2
    return ops.maximum(wz, 0.0) * INV_PI * k * k


def disney_diffuse(ops: ArrayOps, cos_l: Any, cos_v: Any, cos_d2: Any, roughness: Any) -> Any:
    """Burley's diffuse factor ``(1/pi)(1 + (F_D90 - 1) F(L))(1 + (F_D90 - 1) F(V))`` (no colour, no cosine)."""
    fd90_m1 = 2.0 * roughness * cos_d2 - 0.5
    return INV_PI * (1.0 + fd90_m1 * schlick_weight(ops, cos_l)) * (1.0 + fd90_m1 * schlick_weight(ops, cos_v))


def _geometry(ops: ArrayOps, L: Any, V: Any) -> tuple[Any, ...]:
    lx, ly, lz = ops.split(L)
    vx, vy, vz = ops.split(V)
    valid = (lz > 0.0) & (vz > 0.0)
    cos_d2 = ops.clip(0.5 * (1.0 + lx * vx + ly * vy + lz * vz), 0.0, 1.0)
    return lx, ly, lz, vx, vy, vz, valid, cos_d2


def _masked(ops: ArrayOps, valid: Any, colour: Any) -> Any:
    return ops.where(ops.expand(valid), colour, 0.0)


def eval_lambertian(ops: ArrayOps, L: Any, V: Any, base: Any, params: dict[str, Any]) -> Any:
    """``sigma_d / pi * cos theta_L``."""
    _, _, lz, _, _, _, valid, _ = _geometry(ops, L, V)
    return _masked(ops, valid, base * ops.expand(lz * INV_PI))


def eval_disney(ops: ArrayOps, L: Any, V: Any, base: Any, params: dict[str, Any]) -> Any:
    """Disney diffuse + Disney sheen (with tint) times cos theta_L."""
    _, _, lz, _, _, vz, valid, cos_d2 = _geometry(ops, L, V)
    roughness, sheen_weight, sheen_tint = (ops.param(params[k], base) for k in ("roughness", "sheen", "sheen_tint"))
    diffuse = disney_diffuse(ops, lz, vz, cos_d2, roughness) * lz
    lum = ops.luminance(base)
    tint = base / ops.expand(ops.maximum(lum, 1e-6))
    tint = ops.where(ops.expand(lum > 0.0), tint, 1.0)
    c_sheen = 1.0 + (tint - 1.0) * ops.expand(sheen_tint)
    sheen = sheen_weight * schlick_weight(ops, ops.sqrt(cos_d2)) * lz
    return _masked(ops, valid, base * ops.expand(diffuse) + c_sheen * ops.expand(sheen))


def pgc_sheen_terms(ops: ArrayOps, L: Any, V: Any, roughness: Any, sheen_roughness: Any) -> tuple[Any, Any, Any, Any]:
    """The scalar fields of the PGC model: (sheen R D, diffuse f_d cos, R, valid).

    ``eval_cos = sigma_s * sheen + (1 - R) * sigma_d * diffuse`` where valid.
    """
    lx, ly, lz, vx, vy, vz, valid, cos_d2 = _geometry(ops, L, V)
    a_inv, b_inv = ltc_coefficients(ops, vz, sheen_roughness)
    r = sheen_albedo(ops, vz, sheen_roughness)
    ax, ay = sheen_frame(ops, vx, vy)
    wx = lx * ax + ly * ay
    wy = ly * ax - lx * ay
    sheen = r * ltc_density(ops, a_inv, b_inv, wx, wy, lz)
    diffuse = disney_diffuse(ops, lz, vz, cos_d2, roughness) * lz
    return sheen, diffuse, r, valid


def eval_pgc_sheen(ops: ArrayOps, L: Any, V: Any, base: Any, params: dict[str, Any]) -> Any:
    """The paper's model: Zeltner sheen over H_s-scaled Disney diffuse, times cos theta_L."""
    roughness, sheen_roughness, sigma_s = (ops.param(params[k], base)
                                           for k in ("roughness", "sheen_roughness", "sheen_color"))
    sheen, diffuse, r, valid = pgc_sheen_terms(ops, L, V, roughness, sheen_roughness)
    return _masked(ops, valid, sigma_s * ops.expand(sheen) + base * ops.expand((1.0 - r) * diffuse))


EVALUATORS = {"lambertian": eval_lambertian, "disney": eval_disney, "pgc-sheen": eval_pgc_sheen}
"""Model name -> its ``eval_cos(ops, L, V, base, params)`` over an :class:`pgc.arrays.ArrayOps`."""
