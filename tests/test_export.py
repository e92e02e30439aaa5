"""`pgc export`: each format read back by an independent reader (pygltflib/trimesh for glTF, pxr for USD,
the 3DGS .ply and OBJ readers), on a small asset and a three-frame run built here."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgc.cli import main
from pgc.io.asset import write_asset
from pgc.io.export import Animation, sheen_mapping
from pgc.io.timings import write_timings
from pgc.types import GarmentAsset, GaussianSet, Light, Material, Mesh

FRAMES = 3
FPS = 12.0


def grid_garment(n: int = 3) -> Mesh:
    """An n x n quad grid in the z = 0 plane (metres), UV = (x, y) / n, split at the column x = 1 (a seam)."""
    xs = np.arange(n + 1)
    v = np.array([[x, y, 0.0] for y in xs for x in xs], float) / n
    uv, face_uv, faces = [], [], []
    for y in range(n):
        for x in range(n):
            a, b, c, d = y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x
            faces += [[a, b, c], [a, c, d]]
            base = len(uv)  # own UV corners per quad: every edge is a seam
            uv += [[x / n, y / n], [(x + 1) / n, y / n], [(x + 1) / n, (y + 1) / n], [x / n, (y + 1) / n]]
            face_uv += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return Mesh(v, np.array(faces), np.array(uv), np.array(face_uv), np.full(len(faces), 1), name="garment")


def make_asset(brdf: str = "pgc-sheen", params: dict | None = None) -> GarmentAsset:
    garment = grid_garment()
    f = len(garment.faces)
    rng = np.random.default_rng(0)
    gaussians = GaussianSet(parent=np.arange(f), means=rng.normal(0, 0.05, (f, 3)), quats=np.tile([1, 0, 0, 0], (f, 1)),
                            log_scales=np.full((f, 3), -2.0), opacity_logits=np.zeros(f),
                            sh=rng.normal(0, 0.3, (f, 4, 3)))
    body = Mesh(np.array([[0, 0, -0.1], [1, 0, -0.1], [0, 1, -0.1], [1, 1, -0.1]], float),
                np.array([[0, 1, 2], [1, 3, 2]]), face_labels=np.zeros(2), name="body")
    texture = np.zeros((8, 8, 3), np.float32)
    texture[:4] = [0.8, 0.1, 0.1]  # top rows (v near 1) red, bottom rows blue
    texture[4:] = [0.1, 0.1, 0.8]
    params = params if params is not None else {"roughness": 0.7, "sheen_color": [0.6, 0.5, 0.1],
                                                "sheen_roughness": 0.35}
    return GarmentAsset(garment, body, gaussians, Material(brdf, params, texture), Light(np.array([1.0, 0.9, 0.8])),
                        config={"source": {"capture": "/nowhere/capture"}}, figures={"mesh": {"vertices": 4}})


def garment_frames(asset: GarmentAsset) -> np.ndarray:
    """Three frames: rest, a wave along x, then a lift of 0.1 m."""
    v = asset.garment.vertices
    wave = v + np.stack([np.zeros(len(v)), np.zeros(len(v)), 0.2 * np.sin(np.pi * v[:, 0])], 1)
    return np.stack([v, wave, v + [0, 0.1, 0]])


@pytest.fixture
def run_dir(tmp_path):
    """An asset folder and a run folder (run.json, garment.npz, body.npz) animating it."""
    asset = make_asset()
    write_asset(tmp_path / "asset", asset)
    write_timings(tmp_path / "asset", {"seconds": {"mesh": 1.5}})
    run = tmp_path / "run"
    run.mkdir()
    body = np.stack([asset.body.vertices + [0, 0.05 * t, 0] for t in range(FRAMES)])
    np.savez(run / "garment.npz", vertices=garment_frames(asset), faces=asset.garment.faces)
    np.savez(run / "body.npz", vertices=body, faces=asset.body.faces)
    (run / "run.json").write_text(json.dumps({"asset": str(tmp_path / "asset"), "capture": None, "motion": "wave",
                                              "fps": FPS, "frames": FRAMES, "simulator": "test", "figures": {}}))
    return run, asset


def _accessor(gltf, index: int) -> np.ndarray:
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[acc.type]
    dtype = np.uint32 if acc.componentType == 5125 else np.float32
    raw = gltf.binary_blob()[view.byteOffset + (acc.byteOffset or 0):][: acc.count * width * 4]
    return np.frombuffer(raw, dtype).reshape(acc.count, width)


def test_gltf_animated_run_reads_back_in_pygltflib_and_trimesh(run_dir, tmp_path):
    import pygltflib
    import trimesh

    run, asset = run_dir
    out = tmp_path / "out" / "wave.glb"
    assert main(["export", str(run), "--format", "gltf", "--out", str(out)]) == 0
    gltf = pygltflib.GLTF2().load(str(out))
    names = [n.name for n in gltf.nodes]
    assert names == ["garment", "body"]
    prim = gltf.meshes[gltf.nodes[0].mesh].primitives[0]
    assert len(prim.targets) == FRAMES - 1
    base = _accessor(gltf, prim.attributes.POSITION)
    uv = _accessor(gltf, prim.attributes.TEXCOORD_0)
    tri = _accessor(gltf, prim.indices).reshape(-1, 3)
    assert len(tri) == len(asset.garment.faces)
    # every glTF vertex is a garment position: find it, then each frame's target delta must move it there
    frames = garment_frames(asset)
    index = np.argmin(np.linalg.norm(base[:, None] - frames[0][None].astype(np.float32), axis=2), axis=1)
    np.testing.assert_allclose(base, frames[0][index], atol=1e-6)
    for t, target in enumerate(prim.targets, start=1):
        np.testing.assert_allclose(base + _accessor(gltf, target["POSITION"]), frames[t][index], atol=1e-6)
    # glTF UV has v down: the vertex at the top of the grid (y = 1, v = 1) has t = 0
    top = frames[0][index][:, 1] > 0.99
    np.testing.assert_allclose(uv[top, 1], 0.0, atol=1e-6)
    # the animation: one LINEAR sampler, times t / fps, weights one-hot per frame, driving both meshes
    anim = gltf.animations[0]
    np.testing.assert_allclose(_accessor(gltf, anim.samplers[0].input)[:, 0], np.arange(FRAMES) / FPS, rtol=1e-6)
    weights = _accessor(gltf, anim.samplers[0].output).reshape(FRAMES, FRAMES - 1)
    np.testing.assert_array_equal(weights, np.vstack([np.zeros((1, FRAMES - 1)), np.eye(FRAMES - 1)]))
    assert {c.target.node for c in anim.channels} == {0, 1} and anim.samplers[0].interpolation == "LINEAR"
    # the material: our pgc-sheen parameters as KHR_materials_sheen over a dielectric base without specular
    mat = gltf.materials[prim.material]
    assert mat.extensions["KHR_materials_sheen"] == {"sheenColorFactor": pytest.approx([0.6, 0.5, 0.1]),
                                                     "sheenRoughnessFactor": pytest.approx(0.35)}
    assert mat.extensions["KHR_materials_specular"]["specularFactor"] == 0.0
    assert mat.pbrMetallicRoughness.metallicFactor == 0.0
    assert set(gltf.extensionsUsed) == {"KHR_materials_sheen", "KHR_materials_specular"}
    # trimesh, an independent reader: geometry counts and the embedded texture's colours (sRGB, top red)
    scene = trimesh.load(str(out), force="scene")
    garment = scene.geometry["garment"]
    assert len(garment.faces) == len(asset.garment.faces)
    image = np.asarray(garment.visual.material.baseColorTexture.convert("RGB"))
    assert image.shape == (8, 8, 3)
    assert image[0, 0, 0] > 200 and image[0, 0, 2] < 100 and image[-1, 0, 2] > 200  # linear 0.8 -> sRGB 231


def test_sheen_mapping_of_each_brdf():
    assert sheen_mapping(Material("lambertian", {})) is None
    grey = np.full((2, 2, 3), 0.4, np.float32)
    m = sheen_mapping(Material("disney", {"roughness": 0.5, "sheen": 0.6, "sheen_tint": 1.0}, grey))
    assert m == {"sheenColorFactor": pytest.approx([0.6] * 3), "sheenRoughnessFactor": 1.0}  # grey: tint is white
    red = np.zeros((2, 2, 3), np.float32)
    red[..., 0] = 0.5
    m = sheen_mapping(Material("disney", {"sheen": 0.1, "sheen_tint": 1.0}, red))
    np.testing.assert_allclose(m["sheenColorFactor"], [min(0.1 / 0.2126, 1.0), 0, 0], rtol=1e-6)
    assert sheen_mapping(Material("pgc-sheen", {}))["sheenRoughnessFactor"] == pytest.approx(0.5)  # initial value


def test_usd_animated_run_reads_back_in_pxr(run_dir, tmp_path):
    from pxr import Usd, UsdGeom, UsdShade

    run, asset = run_dir
    out = tmp_path / "wave.usda"
    assert main(["export", str(run), "--format", "usd", "--out", str(out)]) == 0
    stage = Usd.Stage.Open(str(out))
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetEndTimeCode() == FRAMES - 1
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    garment = UsdGeom.Mesh(stage.GetPrimAtPath("/PGC/Garment"))
    points = garment.GetPointsAttr()
    assert points.GetNumTimeSamples() == FRAMES
    frames = garment_frames(asset)
    for t in range(FRAMES):
        np.testing.assert_allclose(np.asarray(points.Get(t)), frames[t], atol=1e-6)
    np.testing.assert_allclose(np.asarray(points.Get(0.5)), 0.5 * (frames[0] + frames[1]), atol=1e-6)  # linear
    assert list(garment.GetFaceVertexIndicesAttr().Get()) == asset.garment.faces.reshape(-1).tolist()
    st = UsdGeom.PrimvarsAPI(garment).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying"
    np.testing.assert_allclose(np.asarray(st.ComputeFlattened()), asset.garment.uv[asset.garment.face_uv.reshape(-1)])
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/PGC/Body"))
    np.testing.assert_allclose(np.asarray(body.GetPointsAttr().Get(2)), asset.body.vertices + [0, 0.1, 0], atol=1e-6)
    material, _ = UsdShade.MaterialBindingAPI(garment.GetPrim()).ComputeBoundMaterial()
    surface = material.ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    assert surface.GetInput("roughness").Get() == 1.0 and surface.GetInput("metallic").Get() == 0.0
    tex = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    assert UsdShade.Shader(tex).GetInput("file").Get().path == "wave_albedo.png"
    assert (tmp_path / "wave_albedo.png").is_file()
    prim = material.GetPrim()
    assert prim.GetAttribute("pgc:brdf").Get() == "pgc-sheen"
    np.testing.assert_allclose(list(prim.GetAttribute("pgc:sheen_color").Get()), [0.6, 0.5, 0.1])
    assert not list(tmp_path.glob(".*tmp*"))  # atomic writes leave no temporary files


def test_ply_and_obj_sequences_match_the_frames(run_dir, tmp_path):
    from pgc.io.gaussians_ply import read_world_gaussians_ply
    from pgc.io.mesh import read_mesh
    from pgc.splats.binding import bind

    run, asset = run_dir
    frames = garment_frames(asset)
    assert main(["export", str(run), "--format", "ply-seq", "--out", str(tmp_path / "ply")]) == 0
    files = sorted((tmp_path / "ply").glob("frame_*.ply"))
    assert [f.name for f in files] == [f"frame_{t:04d}.ply" for t in range(FRAMES)]
    header = files[1].read_bytes()[:2000].decode("ascii", "replace")
    assert "pgc_parent" not in header and "property float f_rest_44" in header  # the plain viewer layout
    for t, f in enumerate(files):
        g = read_world_gaussians_ply(f)
        ref = bind(asset.gaussians, frames[t], asset.garment.faces)
        np.testing.assert_allclose(g.means, ref.means, atol=1e-6)
        np.testing.assert_allclose(g.scales, ref.scales, rtol=1e-5)
    assert main(["export", str(run), "--format", "obj-seq", "--out", str(tmp_path / "obj")]) == 0
    for t in range(FRAMES):
        m = read_mesh(tmp_path / "obj" / f"garment_{t:04d}.obj")
        np.testing.assert_allclose(m.vertices, frames[t], atol=1e-6)
        assert m.uv is not None and len(m.uv) == len(asset.garment.uv)
        assert len(read_mesh(tmp_path / "obj" / f"body_{t:04d}.obj").faces) == 2


def test_still_asset_exports_one_frame_without_animation(run_dir, tmp_path):
    import pygltflib

    _, asset = run_dir
    out = tmp_path / "still.glb"
    assert main(["export", str(tmp_path / "asset"), "--format", "gltf", "--out", str(out)]) == 0
    gltf = pygltflib.GLTF2().load(str(out))
    assert not gltf.animations and not gltf.meshes[0].primitives[0].targets
    assert main(["export", str(tmp_path / "asset"), "--format", "ply-seq", "--out", str(tmp_path / "p")]) == 0
    assert [p.name for p in (tmp_path / "p").iterdir()] == ["frame_0000.ply"]


def test_export_errors_name_the_path_and_the_fix(run_dir, tmp_path, capsys):
    run, _ = run_dir
    assert main(["export", str(tmp_path / "missing"), "--format", "gltf", "--out", str(tmp_path / "a.glb")]) == 2
    err = capsys.readouterr().err
    assert "missing" in err and "pgc reconstruct" in err
    assert main(["export", str(tmp_path), "--format", "usd", "--out", str(tmp_path / "a.usda")]) == 2
    assert "neither an asset folder" in capsys.readouterr().err
    assert main(["export", str(run), "--format", "gltf", "--out", str(tmp_path / "a.gltf")]) == 2
    assert ".glb" in capsys.readouterr().err
    assert main(["export", str(run), "--format", "usd", "--out", str(tmp_path / "a.abc")]) == 2
    assert ".usda" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    assert "examples:" in capsys.readouterr().out


def test_animation_rejects_mismatched_frames():
    from pgc.errors import PGCDataError

    with pytest.raises(PGCDataError, match="garment's T"):
        Animation(np.zeros((3, 4, 3)), np.zeros((2, 4, 3)), np.zeros((1, 3), int), 30.0)
