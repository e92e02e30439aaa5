"""Fibre-level fabric truth: the hair-fibre layer of the fibre fabrics (pgc.geometry.fibres.HairLayer), its Mitsuba
scene (pgc_mitsuba.fibres), its sheen, and material.json's ``appearance``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgc.geometry import fibres
from pgc.synth import fabrics
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.types import Camera, Light, Mesh

FIBRE_FABRICS = [name for name, fab in fabrics.FABRICS.items() if fab.hair is not None]
CONTROLS = [name for name, fab in fabrics.FABRICS.items() if fab.hair is None]


def patch(size: float) -> Mesh:
    """A square ``size`` metres in the plane z = 0, normal +z, UVs over [0, 1]^2, two triangles."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * size / 2
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy(), np.full(2, 2, np.int32))


def test_four_or_more_fibre_truths_and_the_controls_keep_their_brdfs():
    assert len(FIBRE_FABRICS) >= 4
    for name in FIBRE_FABRICS:
        fab = fabrics.FABRICS[name]
        assert fab.appearance == fabrics.HAIR_FIBRES and fab.brdf == "lambertian"
        assert 0.2 <= fab.hair.cover() <= 2.0  # a layer that neither vanishes nor buries the surface
    assert {"cotton-sheen", "fleece-sheen", "knit-sheen", "satin-sheen", "lambertian"} <= set(CONTROLS)
    assert fabrics.FABRICS["cotton-sheen"].appearance == "pgc-sheen (in-family control)"
    assert fabrics.FABRICS["lambertian"].appearance == "lambertian (in-family control)"


def test_hair_absorption_inverts_the_colour_mapping():
    color = np.array([0.7, 0.3, 0.05])
    for beta_n in (0.3, 0.6, 0.9):
        sigma = fibres.hair_absorption(color, beta_n)
        d = 5.969 - 0.215 * beta_n + 2.532 * beta_n ** 2 - 10.73 * beta_n ** 3 + 5.574 * beta_n ** 4 \
            + 0.245 * beta_n ** 5
        np.testing.assert_allclose(np.exp(-np.sqrt(sigma) * d), color, rtol=1e-12)
        assert np.all(np.diff(sigma) > 0)  # darker colour, stronger absorption
    assert np.all(fibres.hair_absorption(np.ones(3), 0.5) == 0)  # white fibres absorb nothing


@pytest.mark.parametrize("name", FIBRE_FABRICS)
def test_fibre_layer_geometry_follows_the_fabric(name):
    fab = fabrics.FABRICS[name]
    m = patch(0.05)
    material, _ = fabrics.make_material(fab, m, 32, seed=0)
    fib = fabrics.make_fibres(fab, m, material, seed=4, scale=0.5)
    layer = fab.hair
    assert len(fib.face) == round(layer.density * 0.5 * 0.05 ** 2) and fib.hair == layer
    pts = fib.control_points(m.vertices, m.faces)
    assert pts.shape == (len(fib.face), layer.segments + 1, 3)
    np.testing.assert_allclose(pts[:, 0, 2], 0, atol=1e-12)  # rooted on the surface
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1)
    np.testing.assert_allclose(seg, layer.length / layer.segments, rtol=1e-5)
    tilt = np.arccos(np.clip(np.diff(pts, axis=1)[..., 2] / seg, -1, 1))
    assert layer.rise[0] - 1e-5 <= tilt[:, 0].min() and tilt[:, 0].max() <= layer.rise[1] + 1e-5
    if layer.segments > 1:  # the later segments lie at the layer's angle (jittered by 0.03 rad)
        assert abs(np.median(tilt[:, 1:]) - np.mean(layer.lie)) < 0.1
    assert np.all(pts[..., 2] >= -1e-9) and pts[..., 2].max() <= layer.length + 1e-9
    # colours: the base colour at the roots, grouped; the mean is the albedo layer's fibre colour
    assert fib.palette.shape[1] == 3 and fib.group.max() < len(fib.palette)
    np.testing.assert_allclose(fib.color, np.bincount(fib.group) @ fib.palette / len(fib.group), atol=1e-6)
    R, t = axis_angle_to_matrix(np.array([0.3, 1.0, -0.5])), np.array([0.2, -1.0, 0.4])
    moved = fib.control_points(m.vertices @ R.T + t, m.faces)
    np.testing.assert_allclose(moved, pts @ R.T + t, atol=1e-9)  # they follow any rigid motion


def test_satin_fibres_run_along_the_warp():
    fab = fabrics.FABRICS["satin"]
    m = patch(0.05)
    material, _ = fabrics.make_material(fab, m, 32, seed=0)
    pts = fabrics.make_fibres(fab, m, material, seed=1, scale=0.5).control_points(m.vertices, m.faces)
    d = pts[:, -1] - pts[:, 0]
    along = np.abs(d[:, 1]) / np.linalg.norm(d[:, :2], axis=1)  # |cos| of the angle to the vertical (warp)
    assert np.median(along) > 0.97


# ------------------------------------------------------------------------------------------- rendering


def patch_camera(angle_deg: float, resolution: int, size: float) -> Camera:
    """A camera 0.5 m from the patch centre at ``angle_deg`` from its normal (in the x-z plane), seeing a
    square of side ``size`` / 4 around the centre (so that the patch fills the view up to 80 degrees)."""
    from pgc.types import look_at_pose

    a = np.radians(angle_deg)
    eye = 0.5 * np.array([np.sin(a), 0.0, np.cos(a)])
    R, t = look_at_pose(eye, np.zeros(3))
    f = resolution * 0.5 / (size / 8)
    K = np.array([[f, 0, resolution / 2], [0, f, resolution / 2], [0, 0, 1]])
    return Camera(K, R, t, resolution, resolution, f"patch{angle_deg:g}")


def patch_scene(renderer, fabric: str, seed: int, size: float = 0.12, scale: float = 1.0):
    """A patch of ``fabric`` (its fibres, if any) under the constant unit light: (scene, labels, geometry)."""
    from pgc.roles.scene_renderer import SceneGeometry

    fab = fabrics.FABRICS[fabric]
    m = patch(size)
    material, _ = fabrics.make_material(fab, m, 16, seed=seed)
    material.base_color[:] = material.base_color.reshape(-1, 3).mean(axis=0)  # one colour: the sheen alone
    fib = fabrics.make_fibres(fab, m, material, seed=seed, scale=scale)
    geometry = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), m, material, None, fib)
    scene, labels = renderer.build_scene(geometry, Light(np.ones(3)))
    return scene, labels, geometry


def test_fibre_scene_renders_finite_radiance_and_labels_fibres_as_garment(default_scene_renderer):
    scene, labels, geometry = patch_scene(default_scene_renderer, "fleece", seed=0, size=0.06, scale=0.5)
    cam = patch_camera(30.0, 24, 0.06)
    color, alpha = default_scene_renderer.render_color(scene, cam, 16, seed=0, sampler="ldsampler")
    assert color.shape == (24, 24, 3) and np.all(np.isfinite(color)) and color.min() >= 0
    assert 0.02 < color.mean() < 1.0
    geometry.fibres.color = np.array([1.0, 0.0, 0.0])  # a colour the surface has not: the fibre hits show
    layers = default_scene_renderer.ground_truth_layers(scene, labels, geometry, cam, 2)
    assert np.all(layers["segmentation"] == 2)
    assert layers["mask"].mean() > 0.995  # Mitsuba loses a few curve hits (docs/synth.md, "Fibre truths")
    # fibre hits take the fibres' colour in the albedo layer; a surface hit the base colour
    base = geometry.material.base_color[0, 0, 0]
    fibre_share = (layers["albedo"][..., 0] - base) / (1.0 - base)
    assert 0.05 < fibre_share.mean() < 0.95


def sheen_contrast(renderer, fabric: str, seed: int) -> float:
    """Radiance at 80 degrees from the normal over that at 10 degrees (the rim against the face) of a patch
    of ``fabric`` under a constant light, 24 px, 16 spp."""
    scene, _, _ = patch_scene(renderer, fabric, seed)
    size = 0.12
    value = [renderer.render_color(scene, patch_camera(a, 24, size), 16, seed, "ldsampler")[0].mean()
             for a in (10.0, 80.0)]
    return value[1] / value[0]


@pytest.mark.parametrize("fabric", ["velvet", "cotton"])
def test_a_fibre_layer_has_sheen_that_a_lambertian_surface_has_not(default_scene_renderer, fabric):
    """A Lambertian surface under a constant light has the same radiance from every direction; the fibre layer
    over it is brighter at grazing views (measured: see docs/synth.md, "Fibre truths")."""
    control = sheen_contrast(default_scene_renderer, "lambertian", 0)
    assert control == pytest.approx(1.0, abs=0.01)
    contrast = [sheen_contrast(default_scene_renderer, fabric, seed) for seed in (0, 1)]
    assert min(contrast) > SHEEN_MIN[fabric]


SHEEN_MIN = {"velvet": 2.0, "cotton": 1.3}
"""Lower bounds of the grazing / normal radiance ratio: measured over seeds 0-7 cotton 1.504-1.538 (std 0.013),
velvet 2.624-2.671 (std 0.017) (docs/synth.md, "Fibre truths")."""


# ------------------------------------------------------------------------------------------ material.json


@pytest.mark.parametrize("fabric", ["knit", "cotton-sheen", "lambertian"])
def test_material_record_names_the_appearance(fabric):
    from pgc.synth.ground_truth import GroundTruth, material_record

    fab = fabrics.FABRICS[fabric]
    m = patch(0.05)
    material, normal_map = fabrics.make_material(fab, m, 16, seed=0)
    fib = fabrics.make_fibres(fab, m, material, seed=0, scale=0.2)
    doc = material_record(GroundTruth(m, m, material, Light(np.ones(3)), normal_map, fib), fabric)
    assert doc["appearance"] == fab.appearance and doc["fabric"] == fabric
    assert doc["surface"] == {"brdf": fab.brdf, "params": fab.params}
    if fab.hair is None:
        assert doc["appearance"] == f"{fab.brdf} (in-family control)" and doc["fibre_layer"] is None
    else:
        assert doc["appearance"] == "hair-fibres"
        layer = doc["fibre_layer"]
        assert fibres.HairLayer.from_record(layer) == fab.hair and layer["count"] == len(fib.face)
        np.testing.assert_allclose(layer["colors"], fib.palette, rtol=1e-6)
        np.testing.assert_allclose(layer["sigma_a"], fibres.hair_absorption(fib.palette, fab.hair.azimuthal_roughness))
    json.dumps(doc)  # JSON as it is written


@pytest.mark.slow
def test_a_fibre_capture_writes_its_appearance_and_reads_back(tmp_path, default_scene_renderer, default_body_model):
    from pgc.synth.frames import render_frames
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.ground_truth import read_ground_truth

    out = tmp_path / "knit"
    capture = generate(out, get_preset("tiny", views=1, resolution=32, fibre_scale=0.2), fabric="knit", seed=2,
                       renderer=default_scene_renderer, body_model=default_body_model)
    doc = json.loads((out / "ground_truth" / "material.json").read_text())
    gt = read_ground_truth(out)
    assert doc["appearance"] == "hair-fibres" and gt.fibres.hair == fabrics.FABRICS["knit"].hair
    assert doc["fibre_layer"]["count"] == len(gt.fibres.face) > 1000
    np.testing.assert_array_equal(gt.fibres.palette, np.asarray(doc["fibre_layer"]["colors"], np.float32))
    # the read-back truth renders the capture's view again (another noise seed: the garment's mean radiance)
    view = capture.views[0]
    frame = render_frames(gt, gt.garment.vertices[None], gt.body.vertices[None], [view.camera], spp=16, seed=1,
                          renderer=default_scene_renderer)[0]
    garment = view.segmentation == 2
    assert np.abs(frame["color"][0][garment].mean(axis=0) - view.image[garment].mean(axis=0)).max() < 0.01


def test_an_older_material_json_is_refused_with_the_fix(tmp_path):
    from pgc.errors import PGCDataError
    from pgc.synth.ground_truth import read_ground_truth

    gt = tmp_path / "old" / "ground_truth"
    gt.mkdir(parents=True)
    (gt / "scene.json").write_text("{}")
    (gt / "material.json").write_text(json.dumps({"brdf": "lambertian", "params": {}, "base_color": "x.exr"}))
    with pytest.raises(PGCDataError, match="older 'pgc synth'.*generate it again"):
        read_ground_truth(tmp_path / "old")


def test_the_default_preset_the_demo_scene_writes_a_fibre_truth():
    """The demo's scene (synth preset 'default') is a fibre truth: its material.json names 'hair-fibres' and the
    fibre layer, never a BRDF the fit chooses; the in-family cotton stays available as the control."""
    from pgc.synth.generate import get_preset
    from pgc.synth.ground_truth import GroundTruth, material_record

    preset = get_preset("default")
    fab = fabrics.get_fabric(preset.fabric)
    m = patch(0.05)
    material, normal_map = fabrics.make_material(fab, m, 16, seed=0)
    fib = fabrics.make_fibres(fab, m, material, seed=0, scale=preset.fibre_scale)
    doc = material_record(GroundTruth(m, m, material, Light(np.ones(3)), normal_map, fib), preset.fabric)
    assert doc["appearance"] == fabrics.HAIR_FIBRES and doc["surface"]["brdf"] == "lambertian"
    assert doc["fibre_layer"]["count"] == len(fib.face) > 0
    assert fibres.HairLayer.from_record(doc["fibre_layer"]) == fab.hair
    assert get_preset("default", fabric="cotton-sheen").fabric == "cotton-sheen"
