"""Exports of a garment asset, still or animated, for graphics tools: glTF 2.0 (.glb), USD, per-frame 3DGS
.ply and OBJ sequences. The mapping of our materials onto glTF / UsdPreviewSurface is in docs/export.md.

An :class:`Animation` holds garment vertices per frame (the asset's garment topology) and, optionally, a body
mesh per frame; a still asset is a one-frame animation of its rest garment and capture mesh. Every file is
written atomically. pygltflib and pxr are imported inside the functions that use them.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.atomic import atomic_path
from pgc.io.images import linear_to_srgb
from pgc.types import GarmentAsset, Material, Mesh

FORMATS = ("gltf", "usd", "ply-seq", "obj-seq")


@dataclass
class Animation:
    """Geometry over time: garment (T, V, 3) on the asset's garment faces, body (T, B, 3) on ``body_faces``."""

    garment: np.ndarray
    body: np.ndarray | None
    body_faces: np.ndarray | None
    fps: float

    @classmethod
    def still(cls, asset: GarmentAsset) -> "Animation":
        return cls(asset.garment.vertices[None], asset.body.vertices[None], asset.body.faces, 30.0)

    def __post_init__(self) -> None:
        self.garment = np.asarray(self.garment, np.float64)
        if self.garment.ndim != 3 or self.garment.shape[2] != 3 or not len(self.garment):
            raise PGCDataError(f"animation: garment vertices must be (T, V, 3) with T >= 1, got {self.garment.shape}")
        if self.body is not None:
            self.body = np.asarray(self.body, np.float64)
            if self.body.ndim != 3 or len(self.body) != len(self.garment):
                raise PGCDataError(f"animation: body vertices {self.body.shape} must be (T, B, 3) with the "
                                   f"garment's T = {len(self.garment)}")
        if not self.fps > 0:
            raise PGCDataError(f"animation: fps must be positive, got {self.fps}")

    @property
    def frames(self) -> int:
        return len(self.garment)


# --- material mapping -------------------------------------------------------------------------------------

def _luminance(rgb: np.ndarray) -> float:
    return float(np.dot(rgb, [0.2126, 0.7152, 0.0722]))


def mean_base_color(material: Material) -> np.ndarray:
    """The base colour's mean (linear RGB): the texture's mean, else ``params['base_color']``, else 0.5 grey."""
    if material.base_color is not None:
        return np.asarray(material.base_color, np.float64).reshape(-1, 3).mean(0)
    return np.asarray(material.params.get("base_color", [0.5, 0.5, 0.5]), np.float64).reshape(3)


def sheen_mapping(material: Material) -> dict[str, Any] | None:
    """``KHR_materials_sheen`` factors for our BRDF (docs/export.md), or None for a BRDF without sheen.

    - ``pgc-sheen``: sheenColorFactor = sheen_color, sheenRoughnessFactor = sheen_roughness (both are a sheen
      layer over an albedo-scaled diffuse base; the lobes differ: Zeltner's microfiber fit against glTF's
      Charlie distribution);
    - ``disney``: Disney's sheen is an additive grazing term ``sheen * C_tint * (1 - cos d)^5``;
      sheenColorFactor = clip(sheen * C_tint, 0, 1) with C_tint = lerp(1, base / lum(base), sheen_tint) of the
      mean base colour, sheenRoughnessFactor = 1 (the broadest, most grazing Charlie lobe).
    """
    from pgc.brdfs.parameters import PARAMETERS

    if material.brdf not in PARAMETERS:
        raise PGCDataError(f"material: unknown brdf '{material.brdf}'; exportable: {', '.join(PARAMETERS)}")
    full = {p.name: (p.init[0] if p.size == 1 else list(p.init)) for p in PARAMETERS[material.brdf]}
    full.update({k: v for k, v in material.params.items() if k in full})
    if material.brdf == "pgc-sheen":
        return {"sheenColorFactor": [float(x) for x in np.clip(full["sheen_color"], 0, 1)],
                "sheenRoughnessFactor": float(np.clip(full["sheen_roughness"], 0, 1))}
    if material.brdf == "disney":
        base = mean_base_color(material)
        lum = _luminance(base)
        tint = base / lum if lum > 0 else np.ones(3)
        c = 1.0 + (tint - 1.0) * float(full["sheen_tint"])
        return {"sheenColorFactor": [float(x) for x in np.clip(float(full["sheen"]) * c, 0, 1)],
                "sheenRoughnessFactor": 1.0}
    return None


def _png_bytes(linear: np.ndarray) -> bytes:
    from PIL import Image

    rgb8 = np.rint(linear_to_srgb(np.nan_to_num(linear)) * 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(rgb8).save(buf, format="PNG")
    return buf.getvalue()


def _texture_image(material: Material) -> np.ndarray:
    """The base colour as an image, glTF/USD orientation (row 0 = v 1: our textures are stored that way)."""
    if material.base_color is not None:
        return np.asarray(material.base_color, np.float32)
    return np.broadcast_to(mean_base_color(material).astype(np.float32), (4, 4, 3))


def _split_seams(mesh: Mesh) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """(corner -> position index, uv per new vertex, faces) with one vertex per (position, uv) pair."""
    if mesh.uv is None:
        return np.arange(len(mesh.vertices)), None, mesh.faces
    pairs = np.stack([mesh.faces.ravel(), mesh.face_uv.ravel()], axis=1)
    unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
    return unique[:, 0], mesh.uv[unique[:, 1]], inverse.reshape(-1, 3)


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    return Mesh(vertices, faces).vertex_normals()


# --- glTF ---------------------------------------------------------------------------------------------------

class _Blob:
    """The GLB binary chunk with its bufferViews and accessors."""

    def __init__(self, gltf) -> None:
        self.gltf, self.data = gltf, bytearray()

    def view(self, raw: bytes, target: int | None = None) -> int:
        from pygltflib import BufferView

        while len(self.data) % 4:
            self.data.append(0)
        self.gltf.bufferViews.append(BufferView(buffer=0, byteOffset=len(self.data), byteLength=len(raw),
                                                target=target))
        self.data.extend(raw)
        return len(self.gltf.bufferViews) - 1

    def accessor(self, array: np.ndarray, kind: str, bounds: bool = False, target: int | None = 34962) -> int:
        from pygltflib import FLOAT, UNSIGNED_INT, Accessor

        array = np.ascontiguousarray(array, np.uint32 if kind == "SCALAR_INDEX" else np.float32)
        gl_type = "SCALAR" if kind == "SCALAR_INDEX" else kind
        flat = array.reshape(len(array), -1)
        acc = Accessor(bufferView=self.view(array.tobytes(), target), componentType=UNSIGNED_INT
                       if kind == "SCALAR_INDEX" else FLOAT, count=len(array), type=gl_type)
        if bounds:
            acc.min, acc.max = flat.min(0).tolist(), flat.max(0).tolist()
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1


def _gltf_mesh(blob: _Blob, name: str, frames: np.ndarray, faces: np.ndarray, uv: np.ndarray | None,
               corner: np.ndarray, material: int | None) -> int:
    """A mesh whose frame 0 is the base and frames 1.. are morph targets (POSITION and NORMAL deltas)."""
    from pygltflib import Attributes, Mesh as GMesh, Primitive

    pos = frames[:, corner]
    normals = np.stack([_vertex_normals(f, faces) for f in pos])
    attrs = Attributes(POSITION=blob.accessor(pos[0], "VEC3", bounds=True), NORMAL=blob.accessor(normals[0], "VEC3"))
    if uv is not None:
        attrs.TEXCOORD_0 = blob.accessor(np.stack([uv[:, 0], 1.0 - uv[:, 1]], 1), "VEC2")
    targets = [{"POSITION": blob.accessor(pos[t] - pos[0], "VEC3", bounds=True),
                "NORMAL": blob.accessor(normals[t] - normals[0], "VEC3")} for t in range(1, len(pos))]
    prim = Primitive(attributes=attrs, indices=blob.accessor(faces.reshape(-1), "SCALAR_INDEX", target=34963),
                     material=material, targets=targets or None)
    mesh = GMesh(name=name, primitives=[prim])
    if targets:
        mesh.weights = [0.0] * len(targets)
        mesh.extras = {"targetNames": [f"frame_{t:04d}" for t in range(1, len(pos))]}
    blob.gltf.meshes.append(mesh)
    return len(blob.gltf.meshes) - 1


def write_gltf(path: str | os.PathLike, asset: GarmentAsset, anim: Animation) -> None:
    """A binary glTF 2.0 file: the garment (textured, our material mapped to ``KHR_materials_sheen`` over a
    metallic-roughness base with ``KHR_materials_specular`` at 0) and the body; an animation of T > 1 frames
    is one morph target per frame after the first, driven by one animation ("motion") whose LINEAR weights
    sampler switches target t on at time t / fps."""
    import pygltflib as g

    path = Path(path)
    gltf = g.GLTF2(asset=g.Asset(generator="pgc export", version="2.0"), scene=0, scenes=[g.Scene(nodes=[])])
    blob = _Blob(gltf)
    sheen = sheen_mapping(asset.material)
    gltf.images.append(g.Image(bufferView=blob.view(_png_bytes(_texture_image(asset.material))),
                               mimeType="image/png", name="base_color"))
    gltf.samplers.append(g.Sampler(magFilter=g.LINEAR, minFilter=g.LINEAR_MIPMAP_LINEAR))
    gltf.textures.append(g.Texture(source=0, sampler=0))
    extensions: dict[str, Any] = {"KHR_materials_specular": {"specularFactor": 0.0}}
    if sheen:
        extensions["KHR_materials_sheen"] = sheen
    gltf.materials.append(g.Material(
        name=f"garment ({asset.material.brdf})", doubleSided=True, extensions=extensions,
        pbrMetallicRoughness=g.PbrMetallicRoughness(baseColorTexture=g.TextureInfo(index=0), metallicFactor=0.0,
                                                    roughnessFactor=1.0),
        extras={"pgc": {"brdf": asset.material.brdf, "params": asset.material.params}}))
    gltf.materials.append(g.Material(name="body", pbrMetallicRoughness=g.PbrMetallicRoughness(
        baseColorFactor=[0.6, 0.6, 0.6, 1.0], metallicFactor=0.0, roughnessFactor=0.9)))
    gltf.extensionsUsed = list(extensions)
    corner, uv, faces = _split_seams(asset.garment)
    meshes = [("garment", _gltf_mesh(blob, "garment", anim.garment, faces, uv, corner, 0))]
    if anim.body is not None:
        meshes.append(("body", _gltf_mesh(blob, "body", anim.body, np.asarray(anim.body_faces), None,
                                          np.arange(anim.body.shape[1]), 1)))
    for name, mesh in meshes:
        gltf.nodes.append(g.Node(name=name, mesh=mesh))
        gltf.scenes[0].nodes.append(len(gltf.nodes) - 1)
    if anim.frames > 1:
        n = anim.frames - 1
        times = blob.accessor(np.arange(anim.frames, dtype=np.float32) / anim.fps, "SCALAR", bounds=True, target=None)
        weights = blob.accessor(np.vstack([np.zeros((1, n)), np.eye(n)]).reshape(-1, 1), "SCALAR", target=None)
        anim_g = g.Animation(name="motion", samplers=[g.AnimationSampler(input=times, output=weights,
                                                                          interpolation="LINEAR")])
        anim_g.channels = [g.AnimationChannel(sampler=0, target=g.AnimationChannelTarget(node=i, path="weights"))
                           for i in range(len(meshes))]
        gltf.animations.append(anim_g)
    gltf.buffers.append(g.Buffer(byteLength=len(blob.data)))
    gltf.set_binary_blob(bytes(blob.data))
    if path.suffix.lower() != ".glb":
        raise PGCDataError(f"{path}: glTF is exported as binary .glb; name the output PATH.glb")
    with atomic_path(path) as tmp:
        gltf.save_binary(str(tmp))


# --- USD ----------------------------------------------------------------------------------------------------

USD_SUFFIXES = (".usd", ".usda", ".usdc")


def write_usd(path: str | os.PathLike, asset: GarmentAsset, anim: Animation) -> None:
    """A USD layer: /PGC/Garment and /PGC/Body meshes with time-sampled points (time code = frame, at
    ``fps`` time codes per second), the garment's UVs as ``primvars:st`` (faceVarying) and a
    UsdPreviewSurface material (base-colour texture written beside the layer as ``STEM_albedo.png``,
    roughness 1, metallic 0, specular 0). The fitted BRDF and its parameters are kept as ``pgc:*``
    attributes of the material (UsdPreviewSurface has no sheen)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

    path = Path(path)
    if path.suffix.lower() not in USD_SUFFIXES:
        raise PGCDataError(f"{path}: name the USD output with one of {', '.join(USD_SUFFIXES)}")
    texture = path.with_name(f"{path.stem}_albedo.png")
    with atomic_path(texture) as tmp:
        tmp.write_bytes(_png_bytes(_texture_image(asset.material)))
    with atomic_path(path) as tmp:
        stage = Usd.Stage.CreateNew(str(tmp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(anim.frames - 1)
        stage.SetTimeCodesPerSecond(anim.fps)
        stage.SetFramesPerSecond(anim.fps)
        root = UsdGeom.Xform.Define(stage, "/PGC")
        stage.SetDefaultPrim(root.GetPrim())

        def mesh_prim(name: str, frames: np.ndarray, faces: np.ndarray) -> UsdGeom.Mesh:
            m = UsdGeom.Mesh.Define(stage, f"/PGC/{name}")
            m.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
            m.CreateFaceVertexIndicesAttr(Vt.IntArray(faces.reshape(-1).tolist()))
            m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            points = m.CreatePointsAttr()
            for t, f in enumerate(frames):
                points.Set(Vt.Vec3fArray.FromNumpy(f.astype(np.float32)), Usd.TimeCode(t))
            lo, hi = frames.reshape(-1, 3).min(0), frames.reshape(-1, 3).max(0)
            m.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
            return m

        garment = mesh_prim("Garment", anim.garment, asset.garment.faces)
        garment.CreateDoubleSidedAttr(True)
        if asset.garment.uv is not None:
            st = UsdGeom.PrimvarsAPI(garment).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                            UsdGeom.Tokens.faceVarying)
            st.Set(Vt.Vec2fArray.FromNumpy(asset.garment.uv.astype(np.float32)))
            st.SetIndices(Vt.IntArray(asset.garment.face_uv.reshape(-1).tolist()))
        if anim.body is not None:
            mesh_prim("Body", anim.body, np.asarray(anim.body_faces))
        material = UsdShade.Material.Define(stage, "/PGC/Looks/Garment")
        shader = UsdShade.Shader.Define(stage, "/PGC/Looks/Garment/Surface")
        shader.CreateIdAttr("UsdPreviewSurface")
        for name, value in (("roughness", 1.0), ("metallic", 0.0)):
            shader.CreateInput(name, Sdf.ValueTypeNames.Float).Set(value)
        shader.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
        shader.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
        reader = UsdShade.Shader.Define(stage, "/PGC/Looks/Garment/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
        tex = UsdShade.Shader.Define(stage, "/PGC/Looks/Garment/BaseColor")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(texture.name)
        tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
        shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
        material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        prim = material.GetPrim()
        prim.CreateAttribute("pgc:brdf", Sdf.ValueTypeNames.String).Set(asset.material.brdf)
        for name, value in asset.material.params.items():
            arr = np.atleast_1d(np.asarray(value, np.float64))
            prim.CreateAttribute(f"pgc:{name}", Sdf.ValueTypeNames.DoubleArray).Set(Vt.DoubleArray(arr.tolist()))
        UsdShade.MaterialBindingAPI.Apply(garment.GetPrim()).Bind(material)
        stage.GetRootLayer().Save()


# --- sequences ----------------------------------------------------------------------------------------------

def write_ply_sequence(folder: str | os.PathLike, asset: GarmentAsset, anim: Animation) -> list[Path]:
    """``FOLDER/frame_XXXX.ply``: the Gaussians baked on each frame's garment in the standard 3DGS layout."""
    from pgc.io.gaussians_ply import write_world_gaussians_ply
    from pgc.splats.binding import bind

    folder = Path(folder)
    out = []
    for t, vertices in enumerate(anim.garment):
        out.append(folder / f"frame_{t:04d}.ply")
        write_world_gaussians_ply(out[-1], bind(asset.gaussians, vertices, asset.garment.faces))
    return out


def write_obj_sequence(folder: str | os.PathLike, asset: GarmentAsset, anim: Animation) -> list[Path]:
    """``FOLDER/garment_XXXX.obj`` (with the UV atlas and labels) and ``FOLDER/body_XXXX.obj`` per frame."""
    from pgc.io.mesh import write_mesh

    folder = Path(folder)
    g = asset.garment
    out = []
    for t, vertices in enumerate(anim.garment):
        out.append(folder / f"garment_{t:04d}.obj")
        write_mesh(out[-1], Mesh(vertices, g.faces, g.uv, g.face_uv, g.face_labels, name="garment"))
        if anim.body is not None:
            out.append(folder / f"body_{t:04d}.obj")
            write_mesh(out[-1], Mesh(anim.body[t], anim.body_faces, name="body"))
    return out


def export(fmt: str, out: str | os.PathLike, asset: GarmentAsset, anim: Animation) -> list[Path]:
    """Write ``asset`` animated by ``anim`` in format ``fmt`` (one of :data:`FORMATS`); returns the files."""
    out = Path(out)
    if fmt == "gltf":
        write_gltf(out, asset, anim)
        return [out]
    if fmt == "usd":
        write_usd(out, asset, anim)
        return [out, out.with_name(f"{out.stem}_albedo.png")]
    if fmt == "ply-seq":
        return write_ply_sequence(out, asset, anim)
    if fmt == "obj-seq":
        return write_obj_sequence(out, asset, anim)
    raise PGCDataError(f"export format '{fmt}' is unknown; use one of {', '.join(FORMATS)}")
