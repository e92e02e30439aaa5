"""The synthetic capture against its own ground truth: an independent z-buffer rasteriser of the ground-truth
meshes is the oracle for masks, segmentation, depth and camera conventions."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from conftest import install_distribution
from pgc.errors import PGCDataError
from pgc.types import Camera, Material, Mesh

pytest.importorskip("mitsuba")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, default_scene_renderer, default_body_model):
    from pgc.synth.generate import generate

    out = tmp_path_factory.mktemp("synth") / "tiny"
    generate(out, "tiny", garment="tshirt", fabric="cotton-sheen", seed=1, renderer=default_scene_renderer,
             body_model=default_body_model)
    return out


def rasterize(mesh: Mesh, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Labels (H, W) and camera depth (H, W) (0 = empty) at pixel centres: a plain z-buffer."""
    h, w = camera.height, camera.width
    labels, depth = np.zeros((h, w), np.uint8), np.full((h, w), np.inf)
    uv, z = camera.project(mesh.vertices)
    for f, lab in zip(mesh.faces, mesh.face_labels):
        p, zf = uv[f], z[f]
        if np.any(zf <= 0):
            continue
        x0, y0 = np.maximum(np.floor(p.min(axis=0) - 0.5).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(p.max(axis=0) + 0.5).astype(int), [w, h])
        if x1 <= x0 or y1 <= y0:
            continue
        ys, xs = np.mgrid[y0:y1, x0:x1] + 0.5
        e1, e2 = p[1] - p[0], p[2] - p[0]
        det = e1[0] * e2[1] - e1[1] * e2[0]
        if abs(det) < 1e-12:
            continue
        b1 = ((xs - p[0, 0]) * e2[1] - (ys - p[0, 1]) * e2[0]) / det
        b2 = ((ys - p[0, 1]) * e1[0] - (xs - p[0, 0]) * e1[1]) / det
        inside = (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1)
        zz = 1.0 / ((1 - b1 - b2) / zf[0] + b1 / zf[1] + b2 / zf[2])  # perspective-correct depth
        sub_d = depth[y0:y1, x0:x1]
        closer = inside & (zz < sub_d)
        sub_d[closer] = zz[closer]
        labels[y0:y1, x0:x1][closer] = lab
    depth[~np.isfinite(depth)] = 0
    return labels, depth


@dataclass
class Oracle:
    """The rasterised ground truth at the capture's s x s sub-pixel sample positions, reduced per pixel
    the way the generator documents it."""

    labels: np.ndarray
    """(H, W) label at the pixel centre."""
    coverage: np.ndarray
    """(H, W) covered fraction of the sub-pixel samples."""
    segmentation: np.ndarray
    """(H, W) label covering most samples (background wins ties, as argmax does)."""
    depth: np.ndarray
    """(H, W) mean depth over the covered samples (0 where none)."""


def oracle_for(full: Mesh, camera: Camera, s: int) -> Oracle:
    fine_labels, fine_depth = rasterize(full, camera.scaled(s))  # its pixel centres are our sub-samples
    h, w = camera.height, camera.width
    lab = fine_labels.reshape(h, s, w, s).transpose(0, 2, 1, 3).reshape(h, w, s * s)
    dep = fine_depth.reshape(h, s, w, s).transpose(0, 2, 1, 3).reshape(h, w, s * s)
    counts = np.stack([(lab == k).sum(axis=2) for k in range(3)], axis=-1)
    hits = (lab > 0).sum(axis=2)
    return Oracle(rasterize(full, camera)[0], hits / (s * s), np.argmax(counts, axis=-1),
                  dep.sum(axis=2) / np.maximum(hits, 1))


@pytest.fixture(scope="module")
def capture_and_oracle(tiny):
    from pgc.io.capture import read_capture
    from pgc.io.mesh import read_mesh

    capture = read_capture(tiny)
    full = read_mesh(tiny / "ground_truth" / "full.ply")
    s = capture.metadata["preset"]["gt_samples"]
    return capture, full, [oracle_for(full, v.camera, s) for v in capture.views]


def test_capture_loads_with_the_foundation_reader(capture_and_oracle, tiny):
    capture, _, _ = capture_and_oracle
    assert len(capture.views) == 6
    for v in capture.views:
        assert v.mask is not None and v.segmentation is not None and v.background is not None
        assert set(v.extras) == {"linear", "albedo", "depth"}
        from pgc.io.images import linear_to_srgb

        # the sRGB PNG is the linear render quantised to 8 bits
        np.testing.assert_allclose(linear_to_srgb(v.image), linear_to_srgb(np.clip(v.extras["linear"], 0, 1)),
                                   atol=0.5 / 255 + 1e-6)
    np.testing.assert_allclose(capture.light.radiance, [1.0, 0.96, 0.9])
    assert capture.metadata["garment"] == "tshirt" and capture.labels[2] == "garment"
    assert (tiny / "contact_sheet.png").stat().st_size > 1000


def test_segmentation_and_mask_agree_with_the_projected_meshes(capture_and_oracle):
    """Coverage and labels equal the rasterised meshes at the same sub-pixel samples (8-bit mask files;
    a few samples may fall exactly on an edge shared by two triangles and differ)."""
    capture, _, oracle = capture_and_oracle
    for view, o in zip(capture.views, oracle):
        close = np.abs(view.mask - o.coverage) <= 1 / 255
        assert close.mean() > 0.998, (view.camera.name, close.mean())
        assert (view.segmentation == o.segmentation).mean() > 0.998


def test_cameras_reproject_the_mesh_onto_the_mask_within_a_pixel(capture_and_oracle):
    from scipy.ndimage import distance_transform_edt

    capture, full, oracle = capture_and_oracle
    for view, o in zip(capture.views, oracle):
        uv, _ = view.camera.project(full.vertices)
        to_mask = distance_transform_edt(view.mask == 0)  # pixels to the nearest covered pixel
        px = np.clip(np.floor(uv).astype(int), 0, [view.camera.width - 1, view.camera.height - 1])
        # within a pixel, a diagonal neighbour included (Anny's fingertips are thinner than a pixel at 64 px)
        assert to_mask[px[:, 1], px[:, 0]].max() <= np.sqrt(2) + 1e-9
        # and the other way round: every half-covered pixel is within a pixel of the projected surface
        to_raster = distance_transform_edt(o.labels == 0)
        assert to_raster[view.mask >= 0.5].max() <= 1.0


def test_every_camera_sees_the_whole_person(capture_and_oracle):
    capture, _, _ = capture_and_oracle
    for v in capture.views:
        border = np.concatenate([v.mask[0], v.mask[-1], v.mask[:, 0], v.mask[:, -1]])
        assert border.max() == 0.0 and v.mask.sum() > 100


def test_colour_is_the_person_over_the_empty_dome(capture_and_oracle):
    """Away from the person the image is the background, which is the light's radiance (sRGB 8-bit
    tolerance): this also checks that the path tracer's sensor matches the OpenCV camera."""
    from scipy.ndimage import maximum_filter

    capture, _, oracle = capture_and_oracle
    radiance = capture.light.radiance
    for v, o in zip(capture.views, oracle):
        # no surface within a pixel: thin parts can hide between the sub-pixel samples of the mask
        empty = maximum_filter(o.labels, 3) == 0
        np.testing.assert_allclose(v.background.reshape(-1, 3), np.broadcast_to(radiance, (v.mask.size, 3)),
                                   atol=5e-3)
        np.testing.assert_allclose(v.image[empty], v.background[empty], atol=5e-3)
        person = v.mask == 1
        assert np.abs(v.image[person] - radiance).max(axis=1).mean() > 0.2


def test_depth_and_albedo_layers(capture_and_oracle):
    from scipy.ndimage import maximum_filter, minimum_filter

    from pgc.roles.scene_renderer import SKIN_ALBEDO

    capture, _, oracle = capture_and_oracle
    for view, o in zip(capture.views, oracle):
        same = np.abs(view.mask - o.coverage) <= 1 / 255
        err = np.abs(view.extras["depth"] - o.depth)[same]
        assert np.percentile(err, 99) < 1e-4 and np.all(view.extras["depth"][view.mask == 0] == 0)
        body = (view.mask == 1) & (minimum_filter(o.labels, 3) == 1) & (maximum_filter(o.labels, 3) == 1)
        np.testing.assert_allclose(view.extras["albedo"][body], np.broadcast_to(SKIN_ALBEDO, (body.sum(), 3)),
                                   atol=1e-6)


def test_lambertian_patch_matches_the_analytic_value(default_scene_renderer):
    """A flat Lambertian patch (albedo rho) under a constant environment of radiance L, unoccluded over its
    upper hemisphere, has radiance rho L in every direction. Both the shared BSDF (material_to_bsdf,
    'lambertian' with a texture) and Mitsuba's own 'diffuse' (the body) must give it."""
    from pgc.roles.scene_renderer import SceneGeometry
    from pgc.types import Light, look_at_pose

    rho = np.array([0.5, 0.3, 0.8])
    light = Light(radiance=np.array([1.0, 0.96, 0.9]))
    quad = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float)
    faces = np.array([[0, 2, 1], [0, 3, 2]])  # normal +Y
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    patch = Mesh(quad, faces, uv, faces.copy(), np.full(2, 2, np.int32))
    texture = np.broadcast_to(rho.astype(np.float32), (8, 8, 3)).copy()
    body = quad + [3.0, 0, 0]  # a second patch, away from the first: the body material (Mitsuba 'diffuse')
    geometry = SceneGeometry(body, faces, patch, Material("lambertian", {}, texture), skin_albedo=tuple(rho))
    scene, _ = default_scene_renderer.build_scene(geometry, light)
    for target in ([0.0, 0, 0], [3.0, 0, 0]):
        for elevation in (80.0, 25.0):  # near normal and towards grazing
            e = np.deg2rad(elevation)
            R, t = look_at_pose(np.array(target) + [0, 2 * np.sin(e), 2 * np.cos(e)], np.array(target))
            K = np.array([[200.0, 0, 16], [0, 200.0, 16], [0, 0, 1]])
            color, alpha = default_scene_renderer.render_color(scene, Camera(K, R, t, 32, 32), spp=64, seed=0)
            assert np.all(alpha == 1)
            np.testing.assert_allclose(color.reshape(-1, 3).mean(axis=0), rho * light.radiance, rtol=0.01)


def test_render_frames_reproduces_the_capture_and_follows_the_geometry(tiny, capture_and_oracle,
                                                                       default_scene_renderer):
    from pgc.synth.frames import render_frames
    from pgc.synth.ground_truth import read_ground_truth

    capture, _, _ = capture_and_oracle
    gt = read_ground_truth(tiny)
    cams = [capture.views[0].camera]
    shift = np.array([0.05, 0.0, 0.0])
    g = np.stack([gt.garment.vertices, gt.garment.vertices + shift])
    b = np.stack([gt.body.vertices, gt.body.vertices + shift])
    frames = render_frames(tiny, g, b, cams, spp=16, renderer=default_scene_renderer)
    assert len(frames) == 2 and frames[0]["color"].shape == (1, 64, 64, 3)
    np.testing.assert_allclose(frames[0]["alpha"][0], capture.views[0].mask, atol=0.5 / 255)  # 8-bit file
    fg = capture.views[0].mask == 1
    a, b = frames[0]["color"][0][fg], capture.views[0].image[fg]
    assert np.abs(a.mean(axis=0) - b.mean(axis=0)).max() < 0.01  # same radiance, another noise seed
    assert np.abs(a - b).mean() < 0.06
    # the garment's coverage moves by the projected shift of the garment
    def centroid(m):
        ys, xs = np.nonzero(m > 0)
        w = m[ys, xs]
        return np.array([(xs * w).sum(), (ys * w).sum()]) / w.sum()
    moved = centroid(frames[1]["garment_mask"][0]) - centroid(frames[0]["garment_mask"][0])
    c = gt.garment.vertices.mean(axis=0)
    expected = cams[0].project((c + shift)[None])[0][0] - cams[0].project(c[None])[0][0]
    np.testing.assert_allclose(moved, expected, atol=0.5)


def test_render_frames_rejects_bad_input(tiny, capture_and_oracle, default_scene_renderer):
    from pgc.synth.frames import render_frames
    from pgc.synth.ground_truth import read_ground_truth

    capture, _, _ = capture_and_oracle
    gt = read_ground_truth(tiny)
    with pytest.raises(PGCDataError, match="garment_vertices must have shape"):
        render_frames(gt, np.zeros((1, 5, 3)), gt.body.vertices[None], capture.cameras[:1],
                      renderer=default_scene_renderer)
    with pytest.raises(PGCDataError, match="no synthetic ground truth"):
        read_ground_truth(Path(tiny) / "images")


@pytest.mark.slow
def test_same_seed_gives_byte_identical_output_and_the_cli_works(tmp_path, default_scene_renderer, default_body_model):
    from pgc.cli import main
    from pgc.synth.generate import generate, get_preset

    args = ["--preset", "tiny", "--views", "2", "--resolution", "32", "--seed", "7", "--fabric", "fleece",
            "--detail", "seams", "--fit", "resting", "--looseness", "0.015"]
    assert main(["synth", str(tmp_path / "a"), *args]) == 0
    generate(tmp_path / "b", get_preset("tiny", views=2, resolution=32), fabric="fleece", seed=7, detail="seams",
             fit="resting", looseness=0.015, renderer=default_scene_renderer, body_model=default_body_model)
    files_a = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(tmp_path / "b") for p in (tmp_path / "b").rglob("*") if p.is_file())
    assert files_a == files_b and len(files_a) > 20
    for rel in files_a:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes(), rel
    # the fleece has fibres, labelled garment, rendered and stored, and the detail surface is stored
    assert (tmp_path / "a" / "ground_truth" / "fibres.npz").is_file()
    assert (tmp_path / "a" / "ground_truth" / "detail.npz").is_file()
    # render-frames from the command line on .npz inputs
    from pgc.synth.ground_truth import read_ground_truth

    gt = read_ground_truth(tmp_path / "a")
    np.savez(tmp_path / "g.npz", vertices=gt.garment.vertices[None])
    np.savez(tmp_path / "b.npz", vertices=gt.body.vertices[None])
    assert main(["synth", "render-frames", str(tmp_path / "a"), str(tmp_path / "g.npz"), str(tmp_path / "b.npz"),
                 str(tmp_path / "frames"), "--spp", "4"]) == 0
    with np.load(tmp_path / "frames" / "frame_0000.npz") as z:
        assert z["color"].shape == (2, 32, 32, 3) and z["garment_mask"].max() == 1.0


def test_unknown_names_are_rejected(default_body_model):
    from pgc.synth.fabrics import get_fabric
    from pgc.synth.generate import get_preset

    with pytest.raises(PGCDataError, match="presets: tiny, default, cotton, large, knit"):
        get_preset("huge")
    with pytest.raises(PGCDataError, match="fabrics: cotton"):
        get_fabric("silk")
    from pgc.synth.body import make_body
    from pgc.synth.detail import get_detail
    from pgc.synth.garments import make_garment

    with pytest.raises(PGCDataError, match="--detail.*use one of: none, relief, seams"):
        get_detail("lace")
    with pytest.raises(PGCDataError, match="--fit.*use one of: loose, resting"):
        make_garment(make_body(default_body_model), "tshirt", fit="tight")


def test_stored_body_model_and_motions_reproduce_the_body(tiny, default_body_model):
    from pgc.synth.body import draw_phenotype, make_body
    from pgc.synth.ground_truth import read_body_model, read_ground_truth
    from pgc.synth.motions import make_motion

    body = read_body_model(tiny)
    gt = read_ground_truth(tiny)
    np.testing.assert_allclose(body.vertices, gt.body.vertices, atol=1e-6)  # the capture's body is its rest pose
    assert body.phenotype == draw_phenotype(default_body_model, 1) and body.model == "AnnyBody"
    assert gt.manifest["body"] == {"model": "AnnyBody", "phenotype": body.phenotype, "height_m": round(body.height, 4)}
    with np.load(tiny / "ground_truth" / "motions.npz") as z:
        rotations = z["walk"]
    fresh = make_motion(make_body(default_body_model, body.phenotype), "walk")
    np.testing.assert_allclose(body.pose(rotations), fresh.vertices, atol=1e-5)


def test_render_frames_relights_with_an_environment_map(tiny, capture_and_oracle, default_scene_renderer):
    from pgc.synth.frames import render_frames
    from pgc.synth.ground_truth import read_ground_truth
    from pgc.synth.rig import relight_envmap
    from pgc.types import Light

    capture, _, _ = capture_and_oracle
    gt = read_ground_truth(tiny)
    light = Light(radiance=np.ones(3), envmap=relight_envmap(16, "studio"))
    frame = render_frames(gt, gt.garment.vertices, gt.body.vertices, capture.cameras[:1], light=light, spp=16,
                          renderer=default_scene_renderer)[0]
    color, alpha = frame["color"][0], frame["alpha"][0]
    assert np.all(np.isfinite(color)) and color.min() >= 0
    np.testing.assert_allclose(alpha, capture.views[0].mask, atol=1 / 255)
    # the person is lit differently from the capture's constant light
    person = alpha == 1
    assert np.abs(color[person].mean(axis=0) - capture.views[0].image[person].mean(axis=0)).max() > 0.02


RECORDING_PLUGIN = '''
from pgc.registry import ImplementationSpec, hookimpl
from pgc_mitsuba.synth_scene import MitsubaSceneRenderer

CALLS = []


class RecordingRenderer(MitsubaSceneRenderer):
    """The Mitsuba scene renderer, recording every call with its option max_depth."""

    def build_scene(self, geometry, light):
        CALLS.append(("build_scene", self.options.max_depth))
        return super().build_scene(geometry, light)

    def render_color(self, scene, camera, spp, seed, sampler="independent"):
        CALLS.append(("render_color", self.options.max_depth))
        return super().render_color(scene, camera, spp, seed, sampler)

    def ground_truth_layers(self, scene, labels, geometry, camera, samples=4):
        CALLS.append(("ground_truth_layers", self.options.max_depth))
        return super().ground_truth_layers(scene, labels, geometry, camera, samples)


@hookimpl
def pgc_register_implementations():
    return [ImplementationSpec(role="scene_renderer", name="recording", factory="recplug:RecordingRenderer",
                               description="records its calls", options="pgc_mitsuba.specs_scene:MitsubaSceneOptions",
                               requires=("mitsuba",))]
'''


@pytest.fixture
def recording_renderer(tmp_path, monkeypatch):
    """A scene renderer 'recording' installed as a plugin (distribution rec-pgc-plugin); returns its module."""
    import importlib
    import sys

    install_distribution(tmp_path / "site", monkeypatch, "rec-pgc-plugin", {"recplug": RECORDING_PLUGIN},
                         {"recplug": "recplug"})
    yield importlib.import_module("recplug")
    sys.modules.pop("recplug", None)


def test_the_configured_scene_renderer_renders_with_its_options(tiny, recording_renderer, tmp_path):
    from pgc.cli import main
    from pgc.synth.ground_truth import read_ground_truth

    gt = read_ground_truth(tiny)
    np.savez(tmp_path / "g.npz", vertices=gt.garment.vertices[None])
    np.savez(tmp_path / "b.npz", vertices=gt.body.vertices[None])
    config = tmp_path / "run.toml"
    config.write_text('[scene_renderer]\nuse = "recording"\n[scene_renderer.recording]\nmax_depth = 3\n')
    argv = ["synth", "render-frames", str(tiny), str(tmp_path / "g.npz"), str(tmp_path / "b.npz"),
            str(tmp_path / "frames"), "--spp", "4"]
    assert main([*argv, "--config", str(config)]) == 0
    calls = recording_renderer.CALLS
    assert {name for name, _ in calls} == {"build_scene", "render_color", "ground_truth_layers"}
    assert {depth for _, depth in calls} == {3}  # built with the configured options
    calls.clear()
    assert main(argv) == 0  # the defaults: Mitsuba's own renderer, not the recording one
    assert calls == []


@pytest.mark.slow
def test_three_seeds_give_three_bodies_each_clothed_without_penetration(tmp_path, default_scene_renderer,
                                                                        default_body_model):
    """Each seed draws its own Anny body (the tiny preset, one small view): the captures generate, record their
    body, and the garment starts outside it."""
    from pgc.synth.generate import generate, get_preset
    from pgc.synth.ground_truth import read_body_model, read_ground_truth

    heights = []
    for seed in (0, 1, 2):
        out = tmp_path / f"seed{seed}"
        generate(out, get_preset("tiny", views=1, resolution=32), seed=seed, renderer=default_scene_renderer,
                 body_model=default_body_model)
        gt, body = read_ground_truth(out), read_body_model(out)
        assert gt.manifest["body"]["height_m"] == round(body.height, 4)
        assert gt.manifest["garment_gap_m"]["min"] > 0.02  # the tiny preset's loose tee: 3 cm looseness
        heights.append(body.height)
    assert len({round(h, 3) for h in heights}) == 3, heights


def test_the_detail_height_is_finite_beside_a_degenerate_boundary_loop():
    """A boundary loop of zero length (coincident vertices, seen on a loose dress) has no band to rib: it is
    skipped, not divided by its zero rib period (that made 43992 detail vertices NaN)."""
    from pgc.synth.detail import DETAILS, DetailField
    from pgc.types import Mesh

    xs, ys = np.meshgrid(np.linspace(-0.2, 0.2, 9), np.linspace(0.8, 1.4, 13))
    grid = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, 0.1)], axis=1)
    quads = [(r * 9 + c, r * 9 + c + 1, (r + 1) * 9 + c) for r in range(12) for c in range(8)] + \
            [(r * 9 + c + 1, (r + 1) * 9 + c + 1, (r + 1) * 9 + c) for r in range(12) for c in range(8)]
    point = np.full((3, 3), [0.0, 1.0, 0.3])  # a triangle whose corners coincide: a loop of zero length
    garment = Mesh(np.concatenate([grid, point]), np.array(quads + [(len(grid), len(grid) + 1, len(grid) + 2)]))
    field = DetailField(garment, DETAILS["relief"], seed=0)
    points = np.concatenate([grid, point[:1] + [0.0, 0.0, 0.001]])  # one beside the degenerate loop
    heights = field.height(points, np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    assert np.isfinite(heights).all() and (heights >= 0).all()
