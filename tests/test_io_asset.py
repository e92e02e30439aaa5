"""Asset directory round trip, manifest contents, unknown schema version, atomic writes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.errors import PGCDataError
from pgc.io.asset import read_asset, write_asset
from pgc.io.atomic import atomic_open, write_json
from pgc.types import GarmentAsset, GaussianSet, Light, Material, Mesh


def make_asset(seed: int = 0) -> GarmentAsset:
    rng = np.random.default_rng(seed)
    garment = seamed_cube()
    n = 30
    gaussians = GaussianSet(parent=rng.integers(0, len(garment.faces), n), means=rng.normal(size=(n, 3)),
                            quats=rng.normal(size=(n, 4)), log_scales=rng.normal(-3, 1, (n, 3)),
                            opacity_logits=rng.normal(size=n), sh=rng.normal(size=(n, 9, 3)))
    return GarmentAsset(
        garment=garment, body=seamed_cube(), gaussians=gaussians,
        material=Material("pgc-sheen", {"roughness": 0.7, "sheen_color": [0.2, 0.3, 0.4]},
                          rng.random((8, 16, 3)).astype(np.float32)),
        light=Light(radiance=np.array([1.0, 0.9, 0.8]), envmap=rng.random((4, 8, 3)).astype(np.float32),
                    rotation_deg=45.0),
        config={"splat_renderer": {"use": "torch"}}, figures={"psnr": 31.5})


def test_asset_round_trip(tmp_path):
    asset = make_asset()
    write_asset(tmp_path / "asset", asset)
    manifest = json.loads((tmp_path / "asset" / "manifest.json").read_text())
    assert manifest["schema_version"] == 1 and manifest["versions"]["numpy"] == np.__version__
    assert manifest["config"] == asset.config and manifest["figures"] == asset.figures
    assert manifest["files"]["body"] == "body.obj"  # a body with UVs keeps them (PLY cannot hold seams)
    back = read_asset(tmp_path / "asset")
    np.testing.assert_array_equal(back.garment.vertices, asset.garment.vertices)
    np.testing.assert_array_equal(back.body.face_uv, asset.body.face_uv)
    np.testing.assert_array_equal(back.garment.face_uv, asset.garment.face_uv)
    np.testing.assert_array_equal(back.garment.face_labels, asset.garment.face_labels)
    np.testing.assert_array_equal(back.body.face_labels, asset.body.face_labels)
    for name in ("parent", "means", "quats", "log_scales", "opacity_logits", "sh"):
        np.testing.assert_array_equal(getattr(back.gaussians, name), getattr(asset.gaussians, name))
    assert back.material.brdf == "pgc-sheen" and back.material.params == asset.material.params
    np.testing.assert_array_equal(back.material.base_color, asset.material.base_color)
    np.testing.assert_array_equal(back.light.envmap, asset.light.envmap)
    np.testing.assert_allclose(back.light.radiance, asset.light.radiance)
    assert back.light.rotation_deg == 45.0


def test_body_without_uvs_is_a_ply(tmp_path):
    asset = make_asset()
    asset.body = Mesh(asset.body.vertices, asset.body.faces, face_labels=asset.body.face_labels, name="body")
    write_asset(tmp_path, asset)
    assert json.loads((tmp_path / "manifest.json").read_text())["files"]["body"] == "body.ply"
    back = read_asset(tmp_path)
    np.testing.assert_allclose(back.body.vertices, asset.body.vertices, atol=1e-6)
    np.testing.assert_array_equal(back.body.face_labels, asset.body.face_labels)


def test_unknown_schema_version(tmp_path):
    write_asset(tmp_path, make_asset())
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    manifest["schema_version"] = 99
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(PGCDataError, match=r"manifest\.json: unknown asset schema_version 99; this PGC reads "
                                           r"version 1"):
        read_asset(tmp_path)


def test_incomplete_asset(tmp_path):
    with pytest.raises(PGCDataError, match="no manifest.json; not a PGC asset directory"):
        read_asset(tmp_path)
    write_asset(tmp_path, make_asset())
    (tmp_path / "gaussians.ply").unlink()
    with pytest.raises(PGCDataError, match=r"gaussians\.ply: file not found"):
        read_asset(tmp_path)


def test_atomic_write_keeps_old_file_on_crash(tmp_path):
    target = tmp_path / "data.json"
    write_json(target, {"version": 1})
    with pytest.raises(RuntimeError, match="crash"):
        with atomic_open(target, "w") as f:
            f.write('{"version": 2, "half": ')
            f.flush()
            raise RuntimeError("crash mid-write")
    assert json.loads(target.read_text()) == {"version": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.json"]  # no temporary file left behind


def test_atomic_binary_write_keeps_old_file_on_crash(tmp_path, monkeypatch):
    """The PNG encoder dies after writing half a file: the previous image is untouched."""
    from PIL import Image

    from pgc.io import images

    target = tmp_path / "t.png"
    images.write_image(target, np.full((4, 4, 3), 0.25, np.float32))
    before = target.read_bytes()

    def crashing_save(self, fp, *args, **kwargs):
        with open(fp, "wb") as f:
            f.write(before[: len(before) // 2])
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", crashing_save)
    with pytest.raises(OSError, match="disk full"):
        images.write_image(target, np.full((4, 4, 3), 0.75, np.float32))
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.png"]
