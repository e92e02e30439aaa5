"""The cloth BRDFs as Mitsuba 3 Python BSDFs (differentiable in ``llvm_ad_rgb``), and Material -> scene dict.

Plugins (registered on first use by :func:`register_bsdfs`): ``pgc_lambertian``, ``pgc_disney``,
``pgc_sheen``; the maths is :mod:`pgc.brdfs.maths` evaluated on Dr.Jit arrays (the same formulas as the
numpy/torch/JAX evaluation). Properties: ``base_color`` (a texture; linear RGB) and the parameters of
:data:`pgc.brdfs.parameters.PARAMETERS` (floats; colours as 3-lists or ``mi.ScalarColor3f``), plus
``two_sided`` (default true: a back-side hit is shaded like the front, as for a thin cloth shell).

Sampling: cosine-weighted for the diffuse lobe; the Zeltner sheen lobe exactly (a cosine sample mapped by
the inverse-LTC inverse, pdf = D); the Disney sheen lobe uniformly over the hemisphere (it peaks at grazing
angles where cosine sampling starves). Lobes are chosen with probabilities proportional to their albedo
(estimated from luminances); the pdf returned is the full mixture's. Sampling probabilities are computed on
detached parameters, so gradients flow through the BSDF value only.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pgc.brdfs.maths import EVALUATORS, ltc_coefficients, ltc_density, sheen_albedo, sheen_frame
from pgc.brdfs.parameters import PARAMETERS
from pgc.errors import PGCDataError
from pgc.types import Material
from pgc_mitsuba.ops import drjit_ops
from pgc_mitsuba.runtime import mitsuba

PLUGIN_NAMES = {"lambertian": "pgc_lambertian", "disney": "pgc_disney", "pgc-sheen": "pgc_sheen"}
"""PGC BRDF name -> Mitsuba plugin name."""

_DISNEY_SHEEN_ALBEDO = 0.09
"""Upper bound of the hemispherical albedo of one unit of Disney sheen (measured max 0.086 at grazing):
its lobe-selection weight."""

_registered = False


def register_bsdfs() -> None:
    """Register the three plugins with Mitsuba (idempotent)."""
    global _registered
    if _registered:
        return
    mi = mitsuba()
    for model, plugin in PLUGIN_NAMES.items():
        cls = _make_class(mi, model)
        mi.register_bsdf(plugin, lambda props, cls=cls: cls(props))
    _registered = True


def material_to_bsdf(material: Material, two_sided: bool = True) -> dict[str, Any]:
    """A Mitsuba scene-dict of ``material``'s BSDF (registering the plugins on first use).

    The base colour is the bitmap ``material.base_color`` (linear RGB, v up as in :class:`pgc.types.Mesh`,
    bilinear, clamped at the atlas border) or the constant ``params["base_color"]`` when there is no texture.
    Parameters missing from ``material.params`` take their initial values.
    """
    if material.brdf not in PLUGIN_NAMES:
        raise PGCDataError(f"material.brdf '{material.brdf}' has no Mitsuba BSDF; use one of {sorted(PLUGIN_NAMES)}")
    register_bsdfs()
    mi = mitsuba()
    out: dict[str, Any] = {"type": PLUGIN_NAMES[material.brdf], "two_sided": two_sided,
                           "base_color": base_color_texture(material)}
    for p in PARAMETERS[material.brdf]:
        value = material.params.get(p.name, p.init[0] if p.size == 1 else p.init)
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
        if arr.size != p.size or not np.all(np.isfinite(arr)):
            raise PGCDataError(f"material.params['{p.name}'] must be {p.size} finite number(s), got {value!r}")
        out[p.name] = float(arr[0]) if p.size == 1 else mi.ScalarColor3f(*arr.tolist())
    return out


def base_color_texture(material: Material) -> dict[str, Any]:
    """The scene-dict of the base-colour texture of ``material`` (bitmap or constant)."""
    mi = mitsuba()
    if material.base_color is not None:
        tex = np.asarray(material.base_color, dtype=np.float32)
        if tex.ndim != 3 or tex.shape[2] != 3 or not np.all(np.isfinite(tex)):
            raise PGCDataError(f"material.base_color must be a finite (H, W, 3) texture, got shape {tex.shape}")
        # pgc UVs have v up (texel row (1 - v) H); Mitsuba's bitmap reads row v H: flip the rows.
        return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(tex[::-1])), "raw": True,
                "filter_type": "bilinear", "wrap_mode": "clamp"}
    value = material.params.get("base_color")
    if value is None:
        raise PGCDataError("material has neither a base_color texture nor params['base_color']; give one")
    rgb = np.asarray(value, dtype=np.float64).reshape(-1)
    if rgb.size != 3 or not np.all(np.isfinite(rgb)):
        raise PGCDataError(f"material.params['base_color'] must be 3 finite numbers, got {value!r}")
    return {"type": "rgb", "value": rgb.tolist()}


def _make_class(mi: Any, model: str) -> type:
    import drjit as dr

    ops = drjit_ops()
    evaluate = EVALUATORS[model]
    parameters = PARAMETERS[model]

    class ClothBSDF(mi.BSDF):
        """A PGC cloth BRDF (see module docstring)."""

        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            if "base_color" in props:
                self.base_color = props.get_texture("base_color")
            else:
                self.base_color = mi.load_dict({"type": "rgb", "value": [0.5, 0.5, 0.5]})
            self.two_sided = bool(props.get("two_sided", True))
            self.values: dict[str, Any] = {}
            for p in parameters:
                if p.size == 1:
                    self.values[p.name] = mi.Float(float(props.get(p.name, p.init[0])))
                else:
                    c = props.get(p.name, mi.ScalarColor3f(*p.init))
                    self.values[p.name] = mi.Color3f(c[0], c[1], c[2])
            flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            if self.two_sided:
                flags = flags | mi.BSDFFlags.BackSide
            self.m_components = [flags]
            self.m_flags = flags

        # -- parameters ---------------------------------------------------------------------------------
        def traverse(self, callback: Any) -> None:
            callback.put("base_color", self.base_color, mi.ParamFlags.Differentiable)
            for name, value in self.values.items():
                callback.put(name, value, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys: Any = None) -> None:
            pass

        def to_string(self) -> str:
            return f"ClothBSDF[{model}, {', '.join(self.values)}]"

        # -- helpers ------------------------------------------------------------------------------------
        def _frame(self, si: Any, wo: Any) -> tuple[Any, Any, Any]:
            """(V, L, sign): V = si.wi, L = wo, both mirrored to the front side for a back-side hit."""
            sign = dr.select(si.wi.z < 0, -1.0, 1.0) if self.two_sided else mi.Float(1.0)
            V = mi.Vector3f(si.wi.x, si.wi.y, si.wi.z * sign)
            L = mi.Vector3f(wo.x, wo.y, wo.z * sign)
            return V, L, sign

        def _eval(self, si: Any, V: Any, L: Any, active: Any) -> Any:
            base = self.base_color.eval(si, active)
            return evaluate(ops, L, V, base, self.values)

        def _lobe_weight(self, si: Any, V: Any, active: Any) -> Any:
            """Probability of sampling the non-cosine lobe (detached)."""
            with dr.suspend_grad():
                if model == "lambertian":
                    return mi.Float(0.0)
                lum_d = ops.luminance(self.base_color.eval(si, active))
                if model == "disney":
                    a_s = self.values["sheen"] * _DISNEY_SHEEN_ALBEDO
                    a_d = lum_d
                else:
                    r = sheen_albedo(ops, V.z, self.values["sheen_roughness"])
                    a_s = ops.luminance(self.values["sheen_color"]) * r
                    a_d = (1.0 - r) * lum_d
                total = a_s + a_d
                return dr.detach(dr.select(total > 0, a_s / dr.maximum(total, 1e-12), 0.5))

        def _pdf(self, V: Any, L: Any, w_s: Any) -> Any:
            """Mixture pdf (solid angle) of sampling L given V (front-side frame), detached."""
            with dr.suspend_grad():
                cos_l = dr.maximum(L.z, 0.0)
                p_cos = cos_l / math.pi
                if model == "lambertian":
                    p_other = mi.Float(0.0)
                elif model == "disney":
                    p_other = dr.select(L.z > 0, 1.0 / (2.0 * math.pi), 0.0)
                else:
                    a_inv, b_inv = ltc_coefficients(ops, V.z, self.values["sheen_roughness"])
                    ax, ay = sheen_frame(ops, V.x, V.y)
                    p_other = ltc_density(ops, a_inv, b_inv, L.x * ax + L.y * ay, L.y * ax - L.x * ay, L.z)
                pdf = w_s * p_other + (1.0 - w_s) * p_cos
                return dr.detach(dr.select((V.z > 0) & (L.z > 0), pdf, 0.0))

        # -- BSDF interface -----------------------------------------------------------------------------
        def eval(self, ctx: Any, si: Any, wo: Any, active: bool = True) -> Any:
            V, L, _ = self._frame(si, wo)
            return dr.select(active, self._eval(si, V, L, active), 0.0)

        def pdf(self, ctx: Any, si: Any, wo: Any, active: bool = True) -> Any:
            V, L, _ = self._frame(si, wo)
            return dr.select(active, self._pdf(V, L, self._lobe_weight(si, V, active)), 0.0)

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: bool = True) -> tuple[Any, Any]:
            V, L, _ = self._frame(si, wo)
            value = self._eval(si, V, L, active)
            pdf = self._pdf(V, L, self._lobe_weight(si, V, active))
            return dr.select(active, value, 0.0), dr.select(active, pdf, 0.0)

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: bool = True) -> tuple[Any, Any]:
            V, _, sign = self._frame(si, si.wi)
            w_s = self._lobe_weight(si, V, active)
            cosine = mi.warp.square_to_cosine_hemisphere(sample2)
            if model == "lambertian":
                L = cosine
            elif model == "disney":
                L = dr.select(sample1 < w_s, mi.warp.square_to_uniform_hemisphere(sample2), cosine)
            else:
                with dr.suspend_grad():
                    a_inv, b_inv = ltc_coefficients(ops, V.z, self.values["sheen_roughness"])
                    ax, ay = sheen_frame(ops, V.x, V.y)
                    # inverse of the inverse LTC applied to a cosine sample, in the (X, Y, N) frame
                    fx = (cosine.x - b_inv * cosine.z) / a_inv
                    fy = cosine.y / a_inv
                    lobe = dr.normalize(mi.Vector3f(fx, fy, cosine.z))
                    sheen_dir = mi.Vector3f(lobe.x * ax - lobe.y * ay, lobe.x * ay + lobe.y * ax, lobe.z)
                L = dr.select(sample1 < w_s, sheen_dir, cosine)
            L = dr.detach(L)
            pdf = self._pdf(V, L, w_s)
            value = self._eval(si, V, L, active)
            ok = active & (pdf > 0) & (V.z > 0)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = mi.Vector3f(L.x, L.y, L.z * sign)
            bs.pdf = dr.select(ok, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
            bs.sampled_component = mi.UInt32(0)
            return bs, dr.select(ok, value / dr.maximum(pdf, 1e-20), 0.0)

    ClothBSDF.__name__ = ClothBSDF.__qualname__ = f"ClothBSDF_{PLUGIN_NAMES[model]}"
    return ClothBSDF
