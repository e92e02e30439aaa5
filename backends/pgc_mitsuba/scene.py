"""Mitsuba scenes of a PGC mesh + material + light (the shared setup of rendering and fitting).

An optional occluder mesh (the non-garment faces of a labelled mesh, e.g. the body of a capture; see
:func:`pgc.brdfs.fitdata.split_occluders`) is added as a separate Lambertian shape: it casts shadows and
inter-reflects but is not part of the shaded garment. The emitter is a constant environment of
``light.radiance`` or, with an environment map, the lat-long map times the radiance, rotated by
``light.rotation_deg`` about +Y.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.checks import require_finite
from pgc.errors import PGCDataError
from pgc.types import Light, Material, Mesh
from pgc_mitsuba.bsdfs import material_to_bsdf
from pgc_mitsuba.runtime import mesh_to_mitsuba, mitsuba


def emitter_dict(light: Light) -> dict[str, Any]:
    """The Mitsuba emitter of ``light``; a non-finite or negative radiance, or an environment map of the wrong
    shape or with NaN/Inf, is a :class:`PGCDataError` naming that problem."""
    mi = mitsuba()
    radiance = require_finite("mitsuba", "light.radiance", np.asarray(light.radiance, dtype=np.float64))
    if np.any(radiance < 0):
        raise PGCDataError(f"mitsuba: light.radiance must be non-negative, got {radiance.tolist()}")
    if light.envmap is None:
        return {"type": "constant", "radiance": {"type": "rgb", "value": radiance.tolist()}}
    env = np.asarray(light.envmap, dtype=np.float32)
    if env.ndim != 3 or env.shape[2] != 3 or env.shape[1] != 2 * env.shape[0]:
        raise PGCDataError(f"mitsuba: light.envmap must be an (H, 2H, 3) lat-long map, got shape {env.shape}")
    require_finite("mitsuba", "light.envmap", env)
    rotation = float(require_finite("mitsuba", "light.rotation_deg", float(light.rotation_deg)))
    return {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(env * radiance.astype(np.float32))),
            "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], rotation)}


def scene_dict(mesh: Mesh, material: Material, light: Light, integrator: dict[str, Any],
               occluder: Mesh | None = None, occluder_albedo: float = 0.5,
               smooth_normals: bool = True) -> dict[str, Any]:
    """A scene-dict (no sensor) with the shaded ``mesh``, an optional Lambertian ``occluder`` and the light."""
    mi = mitsuba()
    if material.base_color is not None and mesh.uv is None:
        raise PGCDataError(f"mesh '{mesh.name}' has no UVs but the material has a base_color texture; "
                           "unwrap the mesh or give params['base_color']")
    bsdf = mi.load_dict(material_to_bsdf(material))
    shape = mesh_to_mitsuba(mesh.vertices, mesh.faces, name="garment", uv=mesh.uv, face_uv=mesh.face_uv,
                            bsdf=bsdf, vertex_normals=smooth_normals)
    scene: dict[str, Any] = {"type": "scene", "integrator": integrator, "garment": shape,
                             "light": emitter_dict(light)}
    if occluder is not None:
        grey = mi.load_dict({"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {
            "type": "rgb", "value": [occluder_albedo] * 3}}})
        scene["occluder"] = mesh_to_mitsuba(occluder.vertices, occluder.faces, name="occluder", bsdf=grey,
                                            vertex_normals=smooth_normals)
    return scene
