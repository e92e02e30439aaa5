"""Body occlusion of the garment layers and the far-field lookup through the visible surface."""

import numpy as np
import pytest

from pgc.pipeline.compose import hide_behind, visible_surface_uvs
from pgc.roles.splat_renderer import RenderOutput
from pgc.texture.visibility import render_faces
from pgc.types import Mesh
from conftest import look_at_camera


def plane(z: float, u0: float, name: str) -> Mesh:
    """A 2 m square at depth ``z`` (facing +z) whose UVs span [u0, u0 + 0.5] x [0, 1]."""
    v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[u0, 0], [u0 + 0.5, 0], [u0 + 0.5, 1], [u0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy(), name=name)


def two_planes() -> Mesh:
    front, back = plane(0.0, 0.0, "front"), plane(-0.5, 0.5, "back")
    return Mesh(np.concatenate([front.vertices, back.vertices]), np.concatenate([front.faces, back.faces + 4]),
                np.concatenate([front.uv, back.uv]), np.concatenate([front.face_uv, back.face_uv + 4]), name="two")


CAMERA = look_at_camera([0, 0, 4], [0, 0, 0], 32, 24, 30.0, "cam")


def test_visible_surface_uv_is_the_front_surface_for_points_behind_it():
    mesh = two_planes()
    camera = look_at_camera([0, 0, 4], [0, 0, 0], 32, 24, 300.0, "tele")  # 75 px per metre on the front plane
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.15, 0.15, (40, 2))
    behind = np.column_stack([xy, np.full(40, -0.5)])  # on the back plane, hidden by the front one
    fallback = np.full((40, 2), -7.0)
    uvs = visible_surface_uvs(behind, render_faces(mesh, camera), mesh, camera, fallback)
    # the front plane's UV of the point seen through each back point: along the ray from the camera
    t = 4.0 / 4.5
    seen = behind[:, :2] * t
    expect = np.column_stack([(seen[:, 0] + 1) / 4, (seen[:, 1] + 1) / 2])
    np.testing.assert_allclose(uvs, expect, atol=0.007)  # the UV is that of the pixel centre: half a pixel


def test_visible_surface_uv_falls_back_outside_the_raster():
    mesh = two_planes()
    far_away = np.array([[50.0, 0.0, 0.0], [0.0, 0.0, 10.0]])  # outside the image; behind the camera
    fallback = np.array([[0.1, 0.2], [0.3, 0.4]])
    uvs = visible_surface_uvs(far_away, render_faces(mesh, CAMERA), mesh, CAMERA, fallback)
    np.testing.assert_array_equal(uvs, fallback)


def test_hide_behind_removes_pixels_where_the_occluder_is_nearer():
    rng = np.random.default_rng(1)
    alpha = rng.uniform(0.2, 1.0, (6, 8)).astype(np.float32)
    render = RenderOutput(rng.uniform(0, 1, (6, 8, 3)).astype(np.float32) * alpha[..., None], alpha,
                          np.full((6, 8), 3.0, np.float32))
    occluder = np.full((6, 8), np.inf)
    occluder[:, :3] = 2.0  # nearer: hides
    occluder[:, 3:5] = 4.0  # farther: no effect
    out = hide_behind(render, occluder)
    assert np.all(out.alpha[:, :3] == 0) and np.all(out.color[:, :3] == 0)
    np.testing.assert_array_equal(out.alpha[:, 3:], render.alpha[:, 3:])
    np.testing.assert_array_equal(out.color[:, 3:], render.color[:, 3:])


def test_hide_behind_needs_a_depth():
    with pytest.raises(ValueError, match="depth"):
        hide_behind(RenderOutput(np.zeros((2, 2, 3)), np.ones((2, 2))), np.zeros((2, 2)))


def test_render_faces_with_an_occluder_empties_the_pixels_it_covers():
    garment = plane(0.0, 0.0, "garment")
    body = Mesh(np.array([[-0.2, -0.2, 0.5], [0.2, -0.2, 0.5], [0.2, 0.2, 0.5], [-0.2, 0.2, 0.5]]),
                np.array([[0, 1, 2], [0, 2, 3]]), name="body")
    plain = render_faces(garment, CAMERA)
    hidden = render_faces(garment, CAMERA, occluder=body)
    covered_by_body = render_faces(body, CAMERA).face_id >= 0
    assert covered_by_body.sum() > 4
    assert np.all(hidden.face_id[covered_by_body] == -1) and np.all(np.isinf(hidden.depth[covered_by_body]))
    np.testing.assert_array_equal(hidden.face_id[~covered_by_body], plain.face_id[~covered_by_body])
    # behind the garment the body hides nothing
    behind = Mesh(body.vertices - [0, 0, 1.0], body.faces, name="behind")
    np.testing.assert_array_equal(render_faces(garment, CAMERA, occluder=behind).face_id, plain.face_id)


def _hybrid_renderer(far_source: str, detail: str = "multiplicative"):
    from pgc.config import resolve
    from pgc.pipeline.render import HybridRenderer
    from pgc.splats.init import sample_on_mesh
    from pgc.types import GarmentAsset, Light, Material

    garment = plane(0.0, 0.0, "garment")
    garment = Mesh(garment.vertices, garment.faces, np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32),
                   garment.face_uv, np.full(2, 2, np.int32), name="garment")
    g = sample_on_mesh(garment, 600, np.random.default_rng(4), 0)
    g.opacity_logits[:] = 3.0
    g.log_scales[:] = np.log(0.08)
    texture = np.full((8, 8, 3), 0.5, np.float32)
    asset = GarmentAsset(garment, garment, g, Material("lambertian", {}, texture), Light(np.ones(3)))
    cfg = resolve({"pbr_renderer": {"use": ["torch"], "torch": {"directions": 64, "threads": 1}},
                   "stages": {"render": {"far_source": far_source, "texture_size": 32, "detail": detail}}})
    return HybridRenderer(asset, cfg)


@pytest.mark.parametrize("detail", ["ratio", "residual"])
@pytest.mark.parametrize("far_source", ["splats", "mesh"])
def test_ratio_and_residual_detail_render_the_capture_light_far_field_under_a_novel_light_only(far_source, detail):
    """Details 'ratio' and 'residual': under the capture light no second far field; under a light c times brighter
    the frame's hybrid is c times the capture light's (every layer of a Lambertian garment scales with the light)."""
    pytest.importorskip("torch")
    pytest.importorskip("open3d")
    from pgc.pipeline.render import KernelDecision
    from pgc.types import Light

    renderer = _hybrid_renderer(far_source, detail=detail)
    vertices, light = renderer.asset.garment.vertices, renderer.asset.light
    assert renderer.layers(vertices, CAMERA, light, far_source)["far_capture"] is None
    brighter = Light(light.radiance * 1.7)
    relit_layers = renderer.layers(vertices, CAMERA, brighter, far_source)
    np.testing.assert_allclose(relit_layers["far_capture"].color,
                               renderer.layers(vertices, CAMERA, light, far_source)["far"].color, atol=1e-6)
    decision = KernelDecision(5, far_source, "fixed")
    capture = renderer.frame(vertices, CAMERA, light, decision)
    relit = renderer.frame(vertices, CAMERA, brighter, decision)
    np.testing.assert_allclose(relit["hybrid"], 1.7 * capture["hybrid"], rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("far_source", ["splats", "mesh"])
def test_the_body_in_front_empties_every_garment_layer(far_source):
    pytest.importorskip("torch")
    pytest.importorskip("open3d")
    renderer = _hybrid_renderer(far_source)
    body = Mesh(np.array([[-0.3, -0.3, 0.5], [0.3, -0.3, 0.5], [0.3, 0.3, 0.5], [-0.3, 0.3, 0.5]]),
                np.array([[0, 1, 2], [0, 2, 3]]), name="body")
    layers = renderer.layers(renderer.asset.garment.vertices, CAMERA, renderer.asset.light, far_source, body)
    covered = render_faces(body, CAMERA).face_id >= 0
    assert covered.sum() > 10
    for name in ("near", "far", "pbr"):
        assert np.all(layers[name].alpha[covered] == 0), name
        assert np.all(layers[name].color[covered] == 0), name
        assert layers[name].alpha[~covered].max() > 0.9, name
    if far_source == "mesh":
        assert layers["far"] is layers["pbr"]
    else:  # grey texture under a white sky: the splats' far field is the shaded grey, like the mesh
        inside = (layers["far"].alpha > 0.99) & (layers["pbr"].alpha > 0.99)
        np.testing.assert_allclose(np.median(layers["far"].color[inside], 0),
                                   np.median(layers["pbr"].color[inside], 0), rtol=0.1)


@pytest.mark.parametrize("mode", ["error", "metric"])
@pytest.mark.parametrize("far_source", ["auto", "splats"])
def test_auto_far_field_is_the_one_with_the_lower_kernel_view_error(far_source, mode):
    """'auto' takes the far field whose hybrid scores better on the kernel views: the lower mean absolute error
    (mode 'error') or the better metric (mode 'metric'; SSIM here, higher is better: the 32 x 24 px test view
    is below LPIPS's smallest input)."""
    pytest.importorskip("torch")
    pytest.importorskip("open3d")
    from pgc.config import resolve
    from pgc.pipeline.render import choose_kernel
    from pgc.types import Capture, View

    renderer = _hybrid_renderer(far_source)
    shaded = renderer.pbr.render(renderer.asset.garment, renderer.asset.material, renderer.asset.light, CAMERA)
    seg = np.where(shaded.alpha > 0.5, 2, 0).astype(np.uint8)
    capture = Capture([View(CAMERA, shaded.color, segmentation=seg)], labels={0: "background", 1: "body", 2: "tshirt"})
    kernel = {"mode": mode, "metric": "ssim"}
    cfg = resolve({"stages": {"render": {"far_source": far_source, "kernel_views": 1, "kernel": kernel}}})
    chosen = choose_kernel(renderer, capture, cfg)
    assert chosen.criterion == ("metric:ssim" if mode == "metric" else "error")
    errors = chosen.far_errors
    assert all(np.isfinite(e) and e >= 0 for e in errors.values())
    best = max if mode == "metric" else min
    if far_source == "auto":
        assert set(errors) == {"splats", "mesh"} and chosen.far_source == best(errors, key=errors.get)
    else:
        assert set(errors) == {"splats"} and chosen.far_source == "splats"
    assert chosen.kernel_size % 2 == 1


def test_kernel_rule_compares_the_capture_with_the_capture_light_when_the_run_is_relit():
    """The rule scores renders against the capture images, so it must light them as the capture was lit."""
    pytest.importorskip("torch")
    pytest.importorskip("open3d")
    from pgc.config import resolve
    from pgc.pipeline.render import choose_kernel
    from pgc.types import Capture, Light, View

    renderer = _hybrid_renderer("auto")
    shaded = renderer.pbr.render(renderer.asset.garment, renderer.asset.material, renderer.asset.light, CAMERA)
    seg = np.where(shaded.alpha > 0.5, 2, 0).astype(np.uint8)
    capture = Capture([View(CAMERA, shaded.color, segmentation=seg)], labels={0: "background", 1: "body", 2: "tshirt"})
    cfg = resolve({"stages": {"render": {"far_source": "auto", "kernel_views": 1}}})
    plain = choose_kernel(renderer, capture, cfg)
    assert choose_kernel(renderer, capture, cfg) == plain  # a value of the asset, the capture and the config
    # the run's light is an argument of the frames only, so a relit run keeps the capture light's decision
    frame_plain = renderer.frame(renderer.asset.garment.vertices, CAMERA, renderer.asset.light, plain)
    frame_relit = renderer.frame(renderer.asset.garment.vertices, CAMERA, Light(np.array([0.2, 0.3, 2.5])), plain)
    assert not np.allclose(frame_plain["pbr"], frame_relit["pbr"])
