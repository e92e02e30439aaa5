"""Near-field detail embedded in the garment (knit relief, bands, seams, pocket, folds) and the resting fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pgc.geometry.embedded import DetailSurface, embedded_points
from pgc.synth import detail as D
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.types import Camera, Mesh

pytest.importorskip("mitsuba")

EDGE = 0.04
COARSE = replace(D.DetailSpec(), edge=0.008)
"""The relief's sizes on a coarser fine surface (level 5 on the tiny garment): fast tests."""


@pytest.fixture(scope="module")
def body(default_body_model):
    from pgc.synth.body import make_body

    return make_body(default_body_model)


@pytest.fixture(scope="module")
def tee(body):
    from pgc.synth.garments import make_garment

    return make_garment(body, "tshirt", looseness=0.012, resolution=EDGE, fit="resting")


@pytest.fixture(scope="module")
def relief(tee):
    return D.make_detail(tee, COARSE, seed=3)


def quad(size: float = 0.2) -> Mesh:
    v = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, f, uv, f.copy(), np.full(2, 2, np.int32))


@pytest.mark.parametrize("level", [1, 2, 5])
def test_lattice_subdivision_is_a_watertight_refinement(level):
    m = quad()
    s = DetailSurface(level, np.zeros(0), m.faces, m.uv, m.face_uv)
    n = level
    # vertices: 4 corners, (n - 1) per edge on 5 edges, (n - 1)(n - 2) / 2 inside each face
    assert len(s.face) == 4 + 5 * (n - 1) + 2 * (n - 1) * (n - 2) // 2
    s.offset = np.zeros(len(s.face), np.float32)
    fine = s.mesh(m.vertices)
    assert len(fine.faces) == 2 * n * n
    np.testing.assert_allclose(fine.face_areas().sum(), m.face_areas().sum(), rtol=1e-12)
    np.testing.assert_allclose(fine.face_areas(), 0.2 * 0.2 / 2 / n ** 2, rtol=1e-9)  # the lattice is uniform
    assert np.all(fine.face_normals() @ np.array([0, 0, 1.0]) > 0.999)  # oriented like the parents
    e = np.sort(np.concatenate([fine.faces[:, [0, 1]], fine.faces[:, [1, 2]], fine.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() == 2 and (counts == 1).sum() == 4 * n  # no crack along the shared diagonal
    # texture coordinates interpolate the parent's: here uv = position / size
    tex = fine.uv[fine.face_uv]
    np.testing.assert_allclose(tex, fine.vertices[fine.faces][..., :2] / 0.2, atol=1e-6)


def test_detail_is_embedded_and_follows_a_rigid_motion(tee, relief):
    surface, _ = relief
    rest = surface.vertices(tee.vertices)
    base = embedded_points(tee.vertices, tee.faces, surface.face, surface.bary)
    np.testing.assert_allclose(np.linalg.norm(rest - base, axis=1), surface.offset, atol=1e-9)  # normal offset
    R, t = axis_angle_to_matrix(np.array([0.3, -1.1, 0.5])), np.array([0.4, -0.2, 1.5])
    moved = surface.vertices(tee.vertices @ R.T + t)
    np.testing.assert_allclose(moved, rest @ R.T + t, atol=1e-12)
    # a stretch of the garment moves every fine vertex inside its parent triangle, offsets kept
    stretched = tee.vertices * np.array([1.1, 1.0, 1.0])
    inflated = surface.vertices(stretched)
    base = embedded_points(stretched, tee.faces, surface.face, surface.bary)
    np.testing.assert_allclose(np.linalg.norm(inflated - base, axis=1), surface.offset, atol=1e-9)


def test_relief_is_outward_bounded_and_not_degenerate(body, tee, relief):
    from pgc.sim.collision import signed_distance

    surface, _ = relief
    s = COARSE
    off = surface.offset
    assert np.all(np.isfinite(off)) and off.min() >= 0
    bound = (s.fold_height + max(s.rib_height, s.band_height + s.band_rib_height) + s.seam_height
             + 2.2 * s.pocket_thickness)
    assert off.max() <= bound
    for size in ("rib_height", "seam_height", "pocket_thickness"):  # every feature is there: removing it shows
        without, _ = D.make_detail(tee, replace(s, **{size: 0.0}), seed=3)
        assert np.abs(off - without.offset).max() > 0.5 * getattr(s, size), size
    fine = surface.mesh(tee.vertices)
    assert np.all(np.isfinite(fine.vertices)) and fine.face_areas().min() > 0
    parent_n = tee.face_normals()[surface.parent_face]
    assert np.mean(np.einsum("ij,ij->i", fine.face_normals(), parent_n) > 0) > 0.99  # no flipped relief
    # the relief moves the fabric away from the body, never into it
    pick = np.arange(0, len(fine.vertices), 7)
    base = embedded_points(tee.vertices, tee.faces, surface.face[pick], surface.bary[pick])
    before = signed_distance(base, body.vertices, body.faces)
    after = signed_distance(fine.vertices[pick], body.vertices, body.faces)
    assert after.min() > 0 and np.mean(after >= before - 1e-4) > 0.999


def test_relief_is_seeded_and_deterministic(tee):
    a, _ = D.make_detail(tee, COARSE, seed=3)
    b, _ = D.make_detail(tee, COARSE, seed=3)
    c, _ = D.make_detail(tee, COARSE, seed=4)
    assert a.offset.tobytes() == b.offset.tobytes()
    assert a.offset.tobytes() != c.offset.tobytes()  # the folds are seeded


def test_the_pocket_is_a_plate_on_the_front(tee, relief):
    surface, field = relief
    x0, y0, x1, y1 = field.pocket
    p = embedded_points(tee.vertices, tee.faces, surface.face, surface.bary)
    mid = (np.abs(p[:, 0] - 0.5 * (x0 + x1)) < 0.02) & (np.abs(p[:, 1] - 0.5 * (y0 + y1)) < 0.02)
    front, back = mid & (p[:, 2] > field.z0), mid & (p[:, 2] < field.z0)
    assert front.sum() > 10 and back.sum() > 10
    # with everything else off, the pocket's middle stands off by its thickness and its bulge
    only = replace(COARSE, rib_height=0.0, band_height=0.0, band_rib_height=0.0, seam_height=0.0, fold_height=0.0)
    pocket_only, _ = D.make_detail(tee, only, seed=3)
    assert np.all(pocket_only.offset[back] == 0)
    bulge = np.sin(np.pi * (p[front, 0] - x0) / (x1 - x0)) * np.sin(np.pi * (p[front, 1] - y0) / (y1 - y0))
    np.testing.assert_allclose(pocket_only.offset[front], only.pocket_thickness * (1 + 0.6 * bulge), rtol=1e-5)


def _pixel_hits(surface: Mesh, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixel-centre rays against ``surface`` (Mitsuba): hit mask, camera depth, hit face, hit point."""
    from pgc_mitsuba.runtime import mesh_to_mitsuba, mitsuba

    mi = mitsuba()
    scene = mi.load_dict({"type": "scene", "m": mesh_to_mitsuba(surface.vertices, surface.faces)})
    o, d = camera.rays()
    o, d = np.broadcast_to(o, d.shape).reshape(-1, 3), d.reshape(-1, 3)
    si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*[mi.Float(o[:, k]) for k in range(3)]),
                                      mi.Vector3f(*[mi.Float(d[:, k]) for k in range(3)])))
    valid = np.array(si.is_valid(), bool)
    t = np.array(si.t, np.float64)
    depth = np.where(valid, t * (d @ camera.R[2]), 0.0)
    return valid, depth, np.array(si.prim_index, np.int64), o + t[:, None] * d


def test_detail_appears_in_the_ground_truth_layers(body, tee, relief, default_scene_renderer):
    """Seen head-on, the rendered depth of the detailed garment is the base garment's depth minus the
    relief height at the same place (flat-patch formula h (d . z_cam) / (-d . n)), and the segmentation
    counts the relief as garment."""
    from pgc.synth.generate import framing_sphere
    from pgc.roles.scene_renderer import SceneGeometry
    from pgc.synth.rig import capture_light, dome_cameras
    from pgc.types import Material

    surface, field = relief
    center, radius = framing_sphere("garment", body.height, tee.vertices)
    cam = dome_cameras(4, 96, 96, center=center, distance=2.6, subject_radius=radius, seed=0)[0]
    material = Material("lambertian", {}, np.full((4, 4, 3), 0.5, np.float32))
    light = capture_light()
    layers = {}
    for name, det in (("base", None), ("detail", surface)):
        geometry = SceneGeometry(body.vertices, body.faces, tee, material, detail=det)
        scene, labels = default_scene_renderer.build_scene(geometry, light)
        layers[name] = default_scene_renderer.ground_truth_layers(scene, labels, geometry, cam, samples=1)
    seg_b, seg_d = layers["base"]["segmentation"], layers["detail"]["segmentation"]
    assert (seg_d == 2).sum() >= (seg_b == 2).sum() > 500
    # expected depth change: the relief's (piecewise linear) height where the undisplaced fine surface is hit
    flat = DetailSurface(surface.level, np.zeros_like(surface.offset), tee.faces, tee.uv, tee.face_uv)
    unit = DetailSurface(surface.level, np.ones_like(surface.offset), tee.faces, tee.uv, tee.face_uv)
    flat_v = flat.vertices(tee.vertices)
    normals = unit.vertices(tee.vertices) - flat_v  # the unit offset direction of every fine vertex
    valid, depth, face, point = _pixel_hits(Mesh(flat_v, surface.faces), cam)
    sel = np.nonzero(valid & (seg_b.reshape(-1) == 2) & (seg_d.reshape(-1) == 2))[0]
    tri = surface.faces[face[sel]]
    a = np.concatenate([flat_v[tri].transpose(0, 2, 1), np.ones((len(sel), 1, 3))], axis=1)
    rhs = np.concatenate([point[sel], np.ones((len(sel), 1))], axis=1)
    b = np.linalg.solve(np.einsum("nji,njk->nik", a, a), np.einsum("nji,nj->ni", a, rhs)[..., None])[..., 0]
    h = np.einsum("nk,nk->n", b, surface.offset[tri])
    n = np.einsum("nk,nkd->nd", b, normals[tri])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = cam.rays()[1].reshape(-1, 3)[sel]
    dn = np.einsum("ij,ij->i", d, n)
    expected = -h * (d @ cam.R[2]) / dn  # closer where the relief faces the camera, farther seen from inside
    measured = depth[sel] - layers["detail"]["depth"].reshape(-1)[sel]
    facing = np.abs(dn) > 0.7
    err = np.abs(measured - expected)[facing]
    assert facing.sum() > 300
    assert np.median(err) < 2e-4 and np.quantile(err, 0.8) < 6e-4, (np.median(err), np.quantile(err, 0.8))
    assert np.median(measured[facing]) > 1e-3  # the relief is there, millimetres high


@pytest.mark.parametrize("kind", ["tshirt", "dress"])
def test_resting_garment_hangs_from_the_shoulders(body, kind):
    from pgc.synth.garments import RESTING_TOP_GAP, boundary_loops, make_garment
    from pgc.synth.generate import garment_gap

    resting = make_garment(body, kind, looseness=0.012, resolution=EDGE, fit="resting")
    loose = make_garment(body, kind, looseness=0.03, resolution=EDGE)
    assert len(boundary_loops(resting)) == 4
    gap, before = garment_gap(body.mesh(), resting), garment_gap(body.mesh(), loose)
    assert gap["min"] > 0.5 * RESTING_TOP_GAP  # never inside the body
    assert gap["shoulders_median"] < 2 * RESTING_TOP_GAP < before["shoulders_median"] / 2.5  # loose: 3 cm there
    assert gap["p10"] < 0.01 < before["p10"]


@pytest.fixture(scope="module")
def capture(tmp_path_factory, default_scene_renderer, default_body_model):
    from pgc.synth.generate import generate, get_preset

    out = tmp_path_factory.mktemp("synth_detail") / "tiny"
    generate(out, get_preset("tiny", views=2, resolution=48), fabric="rib-knit-sheen", detail="relief", fit="resting",
             looseness=0.012, seed=2, renderer=default_scene_renderer, body_model=default_body_model)
    return out


def test_the_capture_stores_the_detail_and_its_gap(capture):
    import json

    from pgc.synth.ground_truth import read_ground_truth

    gt = read_ground_truth(capture)
    manifest = json.loads((capture / "ground_truth" / "scene.json").read_text())
    assert gt.detail is not None and manifest["preset"]["detail"] == "relief"
    assert len(gt.detail.offset) == manifest["counts"]["detail_vertices"]
    fine = gt.detail.vertices(gt.garment.vertices)
    assert np.all(np.isfinite(fine)) and gt.detail.mesh(gt.garment.vertices).face_areas().min() > 0
    gap = manifest["garment_gap_m"]
    assert 0 < gap["min"] <= gap["p10"] <= gap["median"] <= gap["p90"] and gap["shoulders_median"] < 0.01
    # fibres are rooted on the relief, not under it
    assert gt.fibres is not None and gt.fibres.offset is not None and gt.fibres.offset.max() > 0.001


def test_render_frames_carry_the_detail_along_a_rigid_motion(capture, default_scene_renderer):
    """Moving body, garment and camera by one rigid motion renders the same frame (the constant light does
    not turn); the detail rides along, so its silhouette stays larger than the bare garment's."""
    from pgc.io.capture import read_capture
    from pgc.synth.frames import render_frames
    from pgc.synth.ground_truth import read_ground_truth

    gt = read_ground_truth(capture)
    cam = read_capture(capture).cameras[0]
    Q, s = axis_angle_to_matrix(np.array([0.2, 0.9, -0.1])), np.array([0.3, 0.1, -0.5])
    moved = Camera(cam.K, cam.R @ Q.T, cam.t - cam.R @ Q.T @ s, cam.width, cam.height, "moved")
    gv, bv = gt.garment.vertices, gt.body.vertices
    a = render_frames(gt, gv, bv, [cam], spp=4, renderer=default_scene_renderer)[0]
    b = render_frames(gt, gv @ Q.T + s, bv @ Q.T + s, [moved], spp=4, renderer=default_scene_renderer)[0]
    assert np.mean(a["segmentation"] == b["segmentation"]) > 0.995
    np.testing.assert_allclose(a["garment_mask"], b["garment_mask"], atol=0.26)  # a sub-sample at most
    assert abs(a["color"].mean() - b["color"].mean()) < 0.01
    gt.detail = None
    bare = render_frames(gt, gv @ Q.T + s, bv @ Q.T + s, [moved], spp=4, renderer=default_scene_renderer)[0]
    assert b["garment_mask"].sum() > bare["garment_mask"].sum() + 2  # pixels of relief (4 measured at 48 px)
