"""The ground-truth folder of a synthetic capture (``OUT/ground_truth/``): write and read.

Layout::

    scene.json            manifest: preset, seed, garment, fabric, render settings, timings, file list
    body.obj              body mesh in the capture A-pose (face label 1)
    garment.obj           garment mesh with UVs (face label 2)
    full.ply              body + garment in one mesh with per-face labels (what a reconstructor should find)
    material.json         appearance ('hair-fibres', or '<brdf> (in-family control)'), the surface BRDF under
                          it (name, parameters; linear RGB), the fibre layer's parameters, fabric preset
    base_color.exr        base-colour texture (linear RGB, rows from v = 1 down to v = 0); base_color.png preview
    normal_map.exr        tangent-space weave normal map, encoded (n + 1) / 2 (absent for flat fabrics)
    fibres.npz            fibres: root face, barycentrics, local directions, length, radius, colour (root offset;
                          fibre truths: colour group per fibre and the group colours)
    detail.npz            near-field detail embedded in garment.obj: subdivision level, per fine vertex offset
    light.json            the capture light (constant RGB radiance)
    envmaps/<kind>.exr    environment maps for relighting ground truth
    body_model.npz        skinned body in the capture pose: vertices, faces, joints, joint names, parents, weights,
                          the body model's name and its phenotype (names, values)
    motions.npz           local joint rotations (T, J, 3, 3) of the body's rig per motion at 30 fps (frame 0 =
                          the capture pose)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.embedded import DetailSurface
from pgc.geometry.fibres import Fibres, HairLayer, hair_absorption
from pgc.io import images as imgio
from pgc.io.atomic import atomic_open, write_json
from pgc.io.limits import read_json
from pgc.io.mesh import read_mesh, write_mesh
from pgc.roles.scene_renderer import SKIN_ALBEDO, SceneGeometry
from pgc.synth.body import SynthBody
from pgc.synth.fabrics import appearance
from pgc.types import Light, Material, Mesh

GT_DIR = "ground_truth"


@dataclass
class GroundTruth:
    """Everything needed to re-render the scene in new poses and lights."""

    body: Mesh
    garment: Mesh
    material: Material
    light: Light
    normal_map: np.ndarray | None = None
    fibres: Fibres | None = None
    skin_albedo: tuple[float, float, float] = SKIN_ALBEDO
    manifest: dict | None = None
    detail: DetailSurface | None = None

    def geometry(self, garment_vertices: np.ndarray | None = None, body_vertices: np.ndarray | None = None
                 ) -> SceneGeometry:
        """The scene at the given vertices (default: the capture pose)."""
        g = self.garment if garment_vertices is None else Mesh(
            garment_vertices, self.garment.faces, self.garment.uv, self.garment.face_uv, self.garment.face_labels,
            self.garment.name)
        bv = self.body.vertices if body_vertices is None else body_vertices
        return SceneGeometry(np.asarray(bv, float), self.body.faces, g, self.material, self.normal_map,
                             self.fibres, self.skin_albedo, self.detail)


def _save_npz(path: Path, **arrays: np.ndarray) -> None:
    with atomic_open(path, "wb") as f:
        np.savez(f, **arrays)


def write_ground_truth(root: str | os.PathLike, gt: GroundTruth, body: SynthBody, motions: dict[str, np.ndarray],
                       envmaps: dict[str, np.ndarray], manifest: dict) -> Path:
    """Write the ground-truth folder under ``root`` and return its path."""
    out = Path(root) / GT_DIR
    out.mkdir(parents=True, exist_ok=True)
    write_mesh(out / "body.obj", gt.body)
    write_mesh(out / "garment.obj", gt.garment)
    full = Mesh(np.concatenate([gt.body.vertices, gt.garment.vertices]),
                np.concatenate([gt.body.faces, gt.garment.faces + len(gt.body.vertices)]),
                face_labels=np.concatenate([gt.body.face_labels, gt.garment.face_labels]), name="full")
    write_mesh(out / "full.ply", full)
    write_json(out / "material.json", material_record(gt, manifest.get("fabric")))
    imgio.write_exr(out / "base_color.exr", gt.material.base_color)
    imgio.write_image(out / "base_color.png", gt.material.base_color)
    if gt.normal_map is not None:
        imgio.write_exr(out / "normal_map.exr", gt.normal_map)
    if gt.fibres is not None:
        f = gt.fibres
        extra = {} if f.offset is None else {"offset": f.offset}
        if f.hair is not None:
            extra.update(group=f.group, palette=f.palette)
        _save_npz(out / "fibres.npz", face=f.face, bary=f.bary, direction=f.direction, length=np.float64(f.length),
                  radius=np.float64(f.radius), color=f.color, **extra)
    if gt.detail is not None:
        _save_npz(out / "detail.npz", level=np.int64(gt.detail.level), offset=gt.detail.offset)
    write_json(out / "light.json", {"radiance": gt.light.radiance.tolist(), "rotation_deg": gt.light.rotation_deg})
    for kind, env in envmaps.items():
        imgio.write_exr(out / "envmaps" / f"{kind}.exr", env)
    write_body_model(out, body)
    _save_npz(out / "motions.npz", **motions)
    write_json(out / "scene.json", dict(manifest, files=sorted(str(p.relative_to(out)) for p in out.rglob("*")
                                                                if p.is_file() and p.name != "scene.json")))
    return out


def material_record(gt: GroundTruth, fabric: str | None) -> dict:
    """The content of material.json: ``appearance`` names what renders the garment (never a fitted BRDF's
    name for a fibre truth), ``surface`` the BRDF of the cloth surface (under the fibres of a fibre truth),
    ``fibre_layer`` the fibres' scattering model with its colours and absorption (fibre truths only)."""
    f = gt.fibres
    layer = None
    if f is not None and f.hair is not None:
        palette = np.asarray(f.palette, np.float64)
        layer = {"model": "mitsuba hair (Chiang et al. 2016) on linear curves", **f.hair.record(),
                 "count": len(f.face), "colors": palette.tolist(),
                 "sigma_a": hair_absorption(palette, f.hair.azimuthal_roughness).tolist()}
    return {"appearance": appearance(gt.material.brdf, None if f is None else f.hair),
            "surface": {"brdf": gt.material.brdf, "params": dict(gt.material.params)},
            "fibre_layer": layer, "fabric": fabric, "base_color": "base_color.exr",
            "normal_map": None if gt.normal_map is None else "normal_map.exr", "skin_albedo": list(gt.skin_albedo)}


def read_ground_truth(root: str | os.PathLike) -> GroundTruth:
    """Read the ground truth of a synthetic capture (``root`` is the capture folder or its ground_truth/)."""
    root = Path(root)
    gt_dir = root if (root / "scene.json").is_file() else root / GT_DIR
    if not (gt_dir / "scene.json").is_file():
        raise PGCDataError(f"{root}: no synthetic ground truth here (expected {GT_DIR}/scene.json); "
                           "make one with 'pgc synth OUT'")
    manifest = read_json(gt_dir / "scene.json", "ground-truth scene.json")
    mat = read_json(gt_dir / "material.json", "ground-truth material.json")
    if "appearance" not in mat or "surface" not in mat:
        raise PGCDataError(f"{gt_dir / 'material.json'}: no 'appearance' and 'surface' (written by an older "
                           "'pgc synth'); delete the capture folder and generate it again")
    material = Material(mat["surface"]["brdf"], mat["surface"]["params"], imgio.read_exr(gt_dir / mat["base_color"]))
    normal_map = imgio.read_exr(gt_dir / mat["normal_map"]) if mat.get("normal_map") else None
    fibres = None
    if (gt_dir / "fibres.npz").is_file():
        z = np.load(gt_dir / "fibres.npz")
        layer = mat.get("fibre_layer")
        fibres = Fibres(z["face"], z["bary"], z["direction"], float(z["length"]), float(z["radius"]), z["color"],
                        z["offset"] if "offset" in z else None,
                        None if layer is None else HairLayer.from_record(layer),
                        z["group"] if layer is not None else None, z["palette"] if layer is not None else None)
    light_doc = read_json(gt_dir / "light.json", "ground-truth light.json")
    garment = read_mesh(gt_dir / "garment.obj")
    detail = None
    if (gt_dir / "detail.npz").is_file():
        z = np.load(gt_dir / "detail.npz")
        detail = DetailSurface(int(z["level"]), z["offset"], garment.faces, garment.uv, garment.face_uv)
    return GroundTruth(read_mesh(gt_dir / "body.obj"), garment, material,
                       Light(np.asarray(light_doc["radiance"]), rotation_deg=light_doc.get("rotation_deg", 0.0)),
                       normal_map, fibres, tuple(mat.get("skin_albedo", SKIN_ALBEDO)), manifest, detail)


def write_body_model(folder: str | os.PathLike, body: SynthBody) -> Path:
    """Write ``folder/body_model.npz`` (the skinned body, its model's name and phenotype) and return its path."""
    path = Path(folder) / "body_model.npz"
    _save_npz(path, vertices=body.vertices, faces=body.faces, joints=body.joints,
              joint_names=np.array(body.joint_names), parents=body.parents, weights=body.weights, model=np.array(body.model),
              phenotype_names=np.array(list(body.phenotype)),
              phenotype_values=np.array(list(body.phenotype.values()), np.float64))
    return path


def read_body_model(root: str | os.PathLike) -> SynthBody:
    """The skinned body stored with a synthetic capture."""
    root = Path(root)
    path = (root if (root / "body_model.npz").is_file() else root / GT_DIR) / "body_model.npz"
    if not path.is_file():
        raise PGCDataError(f"{root}: no synthetic body here (expected {GT_DIR}/body_model.npz); make a capture "
                           "with 'pgc synth OUT'")
    with np.load(path) as z:
        if "joint_names" not in z or "phenotype_names" not in z:
            raise PGCDataError(f"{path}: no joint names or phenotype (written by an older 'pgc synth' for its own "
                               "body); delete the capture folder and generate it again")
        return SynthBody(str(z["model"]), dict(zip(z["phenotype_names"].tolist(), z["phenotype_values"].tolist())),
                         z["vertices"], z["faces"], z["joints"], z["parents"], z["weights"],
                         tuple(z["joint_names"].tolist()))


def body_record(body: SynthBody) -> dict:
    """The body in a capture's metadata: model, phenotype and height (metres)."""
    return {"model": body.model, "phenotype": dict(body.phenotype), "height_m": round(body.height, 4)}
