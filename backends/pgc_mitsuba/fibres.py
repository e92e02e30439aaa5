"""Fibres of a synthetic garment as Mitsuba curve shapes (:class:`pgc.geometry.fibres.Fibres`).

The polylines become ``linearcurve`` shapes (round linear segments of constant radius) whose control
points are set through ``mi.traverse``, so hundreds of thousands of fibres load without a text file.
Mitsuba drops a few curve hits as back faces after Embree has reported them (the ray is then lost, as if it
had missed everything): at most 0.4 % of the rays (looking down velvet's pile), several times more with
tapered tips, so the radius is constant (docs/synth.md, "Fibre truths"). A fibre truth's layer
(``fibres.hair``) is one shape per colour group, shaded by Mitsuba's ``hair`` BSDF with the absorption of
:func:`pgc.geometry.fibres.hair_absorption`; a control's sparse fibres are one shape shaded by the garment's
BRDF in the fibres' colour. Shape ids start with ``FIBRE_ID``.
"""

from __future__ import annotations

import os
import tempfile
from typing import Any

import numpy as np

from pgc.geometry.fibres import Fibres, HairLayer, hair_absorption
from pgc.types import Material
from pgc_mitsuba.bsdfs import material_to_bsdf
from pgc_mitsuba.runtime import mitsuba

FIBRE_ID = "fibres"
"""Id of the first fibre shape; the others are ``fibres_1``, ``fibres_2``, ..."""


def curve_shape(points: np.ndarray, radius: float, bsdf: dict[str, Any], shape_id: str) -> Any:
    """A Mitsuba ``linearcurve`` of N polylines ``points`` (N, K, 3) of ``radius`` (metres) with ``bsdf`` (a
    scene dict)."""
    mi = mitsuba()
    n, k = points.shape[:2]
    r = np.full((n, k, 1), radius, np.float32)
    rows = np.concatenate([points.astype(np.float32), r], axis=-1)
    fd, path = tempfile.mkstemp(suffix=".txt", prefix="pgc_fibre_")  # the plugin loads from a file: one curve
    try:
        with os.fdopen(fd, "w") as f:
            f.write(f"0 0 0 {radius}\n0 0 {radius} {radius}\n")
        shape = mi.load_dict({"type": "linearcurve", "id": shape_id, "filename": path, "bsdf": bsdf})
    finally:
        os.unlink(path)
    params = mi.traverse(shape)
    params["control_point_count"] = n * k
    params["control_points"] = mi.Float(rows.reshape(-1))
    params["segment_indices"] = mi.UInt32((np.arange(n, dtype=np.uint32)[:, None] * k
                                           + np.arange(k - 1, dtype=np.uint32)[None]).reshape(-1))
    params.update()
    return shape


def hair_bsdf(color: np.ndarray, layer: HairLayer) -> dict[str, Any]:
    """The ``hair`` BSDF scene dict of fibres of colour ``color`` (linear RGB) and ``layer``'s roughness."""
    sigma_a = hair_absorption(color, layer.azimuthal_roughness)
    return {"type": "hair", "sigma_a": {"type": "rgb", "value": sigma_a.tolist()},
            "longitudinal_roughness": float(layer.longitudinal_roughness),
            "azimuthal_roughness": float(layer.azimuthal_roughness), "int_ior": float(layer.eta),
            "scale_tilt": float(layer.scale_tilt)}


def fibre_shapes(fibres: Fibres, garment_vertices: np.ndarray, garment_faces: np.ndarray,
                 material: Material) -> dict[str, Any]:
    """The fibres on the given garment vertices as shapes by id (see module docstring)."""
    pts = fibres.control_points(garment_vertices, garment_faces)
    if fibres.hair is None:
        fibre_material = Material(material.brdf, dict(material.params, base_color=fibres.color.tolist()))
        return {FIBRE_ID: curve_shape(pts, fibres.radius, material_to_bsdf(fibre_material), FIBRE_ID)}
    shapes = {}
    for g, color in enumerate(np.asarray(fibres.palette, np.float64)):
        chosen = fibres.group == g
        if chosen.any():
            shape_id = FIBRE_ID if g == 0 else f"{FIBRE_ID}_{g}"
            shapes[shape_id] = curve_shape(pts[chosen], fibres.radius, hair_bsdf(color, fibres.hair), shape_id)
    return shapes
