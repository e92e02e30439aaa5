"""The garment asset directory, the output of ``pgc reconstruct``::

    manifest.json    schema_version, package versions, resolved config, figures, file list and hashes
                     (no time stamp: the same inputs give byte-identical assets)
    garment.obj      garment rest mesh with UV atlas (seams kept) and face labels
    body.ply         full capture-pose mesh: positions float32, faces, face labels (body.obj if it has UVs)
    gaussians.ply    Gaussians bound to garment faces: 3DGS layout baked on the rest mesh + the binding
    albedo.exr       base-colour texture, linear float32 (albedo.png: an 8-bit sRGB preview of it)
    material.json    {"brdf": name, "params": {...}}
    light.json       {"radiance": [r, g, b], "rotation_deg": deg[, "envmap": "light_envmap.exr"]}

Every file is written atomically and the manifest last, with the sha256 of every file (``hashes``): a
directory without a manifest is incomplete, and reading refuses files that do not match their hashes (a write
interrupted while overwriting an asset). Reading checks ``schema_version`` first: an unknown version fails
with a clear message.
"""

from __future__ import annotations

import hashlib
import importlib.metadata as metadata
import json
import os
import platform
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import images as imgio
from pgc.io.atomic import ensure_folder, write_json
from pgc.io.limits import read_json
from pgc.io.gaussians_ply import read_bound_gaussians_ply, write_bound_gaussians_ply
from pgc.io.mesh import read_mesh, write_mesh
from pgc.types import GarmentAsset, Light, Material

SCHEMA_VERSION = 1
MANIFEST = "manifest.json"
VERSIONED_PACKAGES = ("pgc", "numpy", "scipy", "trimesh", "torch", "jax", "mitsuba", "drjit", "open3d-cpu",
                      "pycolmap", "pymeshlab", "xatlas", "onnxruntime", "opencv-python-headless")


def package_versions(names: tuple[str, ...] = VERSIONED_PACKAGES) -> dict[str, str]:
    """The Python version and the installed versions of ``names`` (from package metadata, nothing imported);
    packages that are not installed are left out."""
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def write_asset(path: str | os.PathLike, asset: GarmentAsset) -> None:
    """Write ``asset`` as an asset directory (created if needed; existing files are replaced)."""
    root = ensure_folder(path)
    files: dict[str, str] = {"garment": "garment.obj", "body": "body.ply" if asset.body.uv is None else "body.obj",
                             "gaussians": "gaussians.ply", "material": "material.json", "light": "light.json"}
    write_mesh(root / files["garment"], asset.garment)
    write_mesh(root / files["body"], asset.body)
    write_bound_gaussians_ply(root / files["gaussians"], asset.gaussians, asset.garment.vertices,
                              asset.garment.faces)
    material: dict[str, Any] = {"brdf": asset.material.brdf, "params": asset.material.params}
    if asset.material.base_color is not None:
        files["albedo"] = material["base_color"] = "albedo.exr"
        files["albedo_preview"] = "albedo.png"
        imgio.write_exr(root / files["albedo"], asset.material.base_color)
        imgio.write_image(root / files["albedo_preview"], asset.material.base_color)
    write_json(root / files["material"], material)
    light: dict[str, Any] = {"radiance": asset.light.radiance.tolist(), "rotation_deg": float(asset.light.rotation_deg)}
    if asset.light.envmap is not None:
        files["envmap"] = light["envmap"] = "light_envmap.exr"
        imgio.write_exr(root / files["envmap"], asset.light.envmap)
    write_json(root / files["light"], light)
    write_json(root / MANIFEST, {  # last: it records the hashes that tie the files of this write together
        "schema_version": SCHEMA_VERSION,
        "versions": package_versions(),
        "files": files,
        "hashes": {key: file_hash(root / name) for key, name in files.items()},
        "counts": {"garment_vertices": len(asset.garment.vertices), "garment_faces": len(asset.garment.faces),
                   "gaussians": len(asset.gaussians), "sh_degree": asset.gaussians.sh_degree},
        "heldout_views": list(asset.heldout_views),
        "config": asset.config,
        "figures": asset.figures,
    })


def file_hash(path: Path) -> str:
    """sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def asset_file(root: Path, name: object, where: str) -> Path:
    """The path of an asset file named ``name`` in ``where`` (a field of a file of the asset ``root``): a
    relative path inside the asset folder (no absolute path, no ``..``, no symbolic link leading outside)."""
    pure = PurePosixPath(name) if isinstance(name, str) else None
    if pure is None or not name or pure.is_absolute() or "\\" in name or ".." in pure.parts or not pure.name:
        raise PGCDataError(f"{where}: {name!r} is not a relative path inside the asset folder {root}; asset files "
                           "are named relative to the folder, without '..' (re-create the asset with pgc reconstruct)")
    path = root / pure
    real_root = os.path.realpath(root)
    if os.path.commonpath([real_root, os.path.realpath(path)]) != real_root:
        raise PGCDataError(f"{where}: {name!r} leads outside the asset folder {root} (through a symbolic link to "
                           f"{os.path.realpath(path)}); copy the file into the asset instead of linking it")
    return path


def verify_files(root: Path, manifest: dict[str, Any]) -> None:
    """Refuse an asset folder whose files are missing, lie outside it or are not the ones its manifest was
    written with (an interrupted overwrite, or files copied in from another asset)."""
    hashes = manifest.get("hashes")
    if not isinstance(hashes, dict):
        raise PGCDataError(f"{root / MANIFEST}: no 'hashes' of the asset files (written by an older PGC, or "
                           "edited); re-create the asset with pgc reconstruct")
    for key, name in manifest["files"].items():
        path = asset_file(root, name, f"{root / MANIFEST}: files.{key}")
        if not path.is_file():
            raise PGCDataError(f"{path}: file not found; the asset folder {root} is incomplete. Rerun pgc reconstruct "
                               "(completed stages are reused)")
        if hashes.get(key) != file_hash(path):
            raise PGCDataError(f"{path}: does not match the hash recorded in {MANIFEST}: the folder mixes files of "
                               "two writes (interrupted overwrite?) or the file was edited. Rerun pgc reconstruct "
                               f"--out {root} (completed stages are reused)")


def _load_json(path: Path) -> Any:
    return read_json(path, "PGC asset file")


def read_manifest(path: str | os.PathLike) -> dict[str, Any]:
    """The manifest of an asset directory, after checking its schema version and the hashes of its files."""
    root = Path(path)
    if not (root / MANIFEST).is_file():
        raise PGCDataError(f"{root}: no {MANIFEST}; not a PGC asset directory (or an incomplete write)")
    manifest = _load_json(root / MANIFEST)
    version = manifest.get("schema_version") if isinstance(manifest, dict) else None
    if version != SCHEMA_VERSION:
        raise PGCDataError(f"{root / MANIFEST}: unknown asset schema_version {version!r}; this PGC reads version "
                           f"{SCHEMA_VERSION}. Re-create the asset with this PGC (pgc reconstruct) or use the PGC "
                           "version that wrote it")
    if not isinstance(manifest.get("files"), dict):
        raise PGCDataError(f"{root / MANIFEST}: field 'files' must be an object naming the asset files")
    verify_files(root, manifest)
    return manifest


def _listed(root: Path, manifest: dict[str, Any], name: Any, where: str) -> Path:
    """An asset file that another asset file names: inside the folder and among the manifest's (hashed) files."""
    path = asset_file(root, name, where)
    if name not in manifest["files"].values():
        raise PGCDataError(f"{where}: {name!r} is not among the files of {root / MANIFEST}, so its hash is not "
                           "checked; re-create the asset with pgc reconstruct")
    return path


def read_asset(path: str | os.PathLike) -> GarmentAsset:
    """Read an asset directory written by :func:`write_asset`."""
    root = Path(path)
    manifest = read_manifest(root)
    files = manifest["files"]

    def file(key: str) -> Path:
        if key not in files:
            raise PGCDataError(f"{root / MANIFEST}: 'files' has no entry '{key}'")
        return asset_file(root, files[key], f"{root / MANIFEST}: files.{key}")

    garment = read_mesh(file("garment"), name="garment")
    body = read_mesh(file("body"), name="body")
    gaussians = read_bound_gaussians_ply(file("gaussians"))
    if len(gaussians) and gaussians.parent.max() >= len(garment.faces):
        raise PGCDataError(f"{file('gaussians')}: parent face {gaussians.parent.max()} out of range for the "
                           f"{len(garment.faces)} faces of {file('garment').name}")
    mat = _load_json(file("material"))
    if not isinstance(mat, dict) or not isinstance(mat.get("brdf"), str):
        raise PGCDataError(f"{file('material')}: needs a string field 'brdf'")
    base_color = imgio.read_exr(_listed(root, manifest, mat["base_color"], f"{file('material')}: base_color")) \
        if mat.get("base_color") else None
    material = Material(brdf=mat["brdf"], params=mat.get("params", {}), base_color=base_color)
    lt = _load_json(file("light"))
    radiance = np.asarray(lt.get("radiance", [1, 1, 1]), dtype=np.float64) if isinstance(lt, dict) else None
    if radiance is None or radiance.shape != (3,) or not np.all(np.isfinite(radiance)):
        raise PGCDataError(f"{file('light')}: 'radiance' must be 3 finite numbers")
    envmap = imgio.read_exr(_listed(root, manifest, lt["envmap"], f"{file('light')}: envmap")) \
        if lt.get("envmap") else None
    light = Light(radiance=radiance, envmap=envmap, rotation_deg=float(lt.get("rotation_deg", 0.0)))
    return GarmentAsset(garment=garment, body=body, gaussians=gaussians, material=material, light=light,
                        heldout_views=[str(v) for v in manifest.get("heldout_views", [])],
                        config=manifest.get("config", {}), figures=manifest.get("figures", {}))
