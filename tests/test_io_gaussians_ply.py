"""3DGS .ply: the standard layout, known values from a hand-written file, exact binding round trip."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.io.gaussians_ply import (STANDARD_PROPERTIES, read_bound_gaussians_ply, read_world_gaussians_ply,
                                  write_bound_gaussians_ply, write_world_gaussians_ply)
from pgc.types import GaussianSet, WorldGaussians


def _header_properties(path):
    text = path.read_bytes().split(b"end_header")[0].decode()
    return [line.split()[-1] for line in text.splitlines() if line.startswith("property")]


def _random_world(n, degree, seed=0):
    rng = np.random.default_rng(seed)
    return WorldGaussians(means=rng.normal(size=(n, 3)), quats=rng.normal(size=(n, 4)),
                          scales=np.exp(rng.normal(-4, 1, size=(n, 3))), opacities=rng.uniform(0.01, 0.99, n),
                          sh=rng.normal(size=(n, (degree + 1) ** 2, 3)))


def test_standard_property_order_and_channel_grouping(tmp_path):
    g = _random_world(5, 3)
    k, c = np.meshgrid(np.arange(16), np.arange(3), indexing="ij")
    g.sh[:] = (100 * c + k)[None]  # coefficient k of channel c holds 100 c + k
    write_world_gaussians_ply(tmp_path / "g.ply", g)
    props = _header_properties(tmp_path / "g.ply")
    assert props[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert props[9:54] == [f"f_rest_{i}" for i in range(45)]
    assert props[54:] == ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    assert props == STANDARD_PROPERTIES
    raw = np.frombuffer(
        (tmp_path / "g.ply").read_bytes().split(b"end_header\n", 1)[1], dtype="<f4").reshape(5, 62)
    # f_rest grouped by channel: f_rest_{c * 15 + (k - 1)} = coefficient k of channel c
    for ch in range(3):
        np.testing.assert_array_equal(raw[:, 9 + 15 * ch: 9 + 15 * (ch + 1)],
                                      np.broadcast_to(100 * ch + np.arange(1, 16), (5, 15)))
    np.testing.assert_allclose(raw[:, 54], np.log(g.opacities / (1 - g.opacities)), rtol=1e-5)
    np.testing.assert_allclose(raw[:, 55:58], np.log(g.scales), rtol=1e-6)


def test_read_hand_written_file_known_values(tmp_path):
    """A degree-0 file written byte by byte: activation of opacity and scale, wxyz quaternion."""
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
             "rot_0", "rot_1", "rot_2", "rot_3"]
    values = [1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.0, np.log(0.5), 0.0, np.log(2.0), 1.0, 0.0, 0.0, 0.0]
    header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n" + "".join(
        f"property float {n}\n" for n in names) + "end_header\n"
    (tmp_path / "h.ply").write_bytes(header.encode() + struct.pack("<14f", *values))
    g = read_world_gaussians_ply(tmp_path / "h.ply")
    np.testing.assert_allclose(g.means, [[1, 2, 3]])
    np.testing.assert_allclose(g.scales, [[0.5, 1.0, 2.0]], rtol=1e-6)
    np.testing.assert_allclose(g.opacities, [0.5])
    np.testing.assert_allclose(g.quats, [[1, 0, 0, 0]])
    assert g.sh.shape == (1, 1, 3)
    np.testing.assert_allclose(g.sh[0, 0], [0.1, 0.2, 0.3], rtol=1e-6)


@pytest.mark.parametrize("degree", [0, 1, 3])
def test_world_round_trip(tmp_path, degree):
    g = _random_world(50, degree, seed=degree)
    write_world_gaussians_ply(tmp_path / "w.ply", g)
    back = read_world_gaussians_ply(tmp_path / "w.ply")
    assert back.sh.shape == g.sh.shape
    for name in ("means", "quats", "sh"):
        np.testing.assert_allclose(getattr(back, name), getattr(g, name), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(back.scales, g.scales, rtol=1e-5)
    np.testing.assert_allclose(back.opacities, g.opacities, rtol=1e-5)


def test_zero_scale_and_extreme_opacity_stay_finite(tmp_path):
    g = _random_world(3, 0)
    g.scales[0] = 0.0
    g.opacities[:] = [0.0, 1.0, 0.5]
    write_world_gaussians_ply(tmp_path / "z.ply", g)
    back = read_world_gaussians_ply(tmp_path / "z.ply")
    assert np.all(np.isfinite(back.scales)) and np.all(back.scales[0] < 1e-30)
    assert np.all(np.isfinite(back.opacities)) and back.opacities[0] < 1e-6 and back.opacities[1] > 1 - 1e-6


def _mesh_and_gaussians(n=40, seed=0):
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(6, 3))
    faces = np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]])
    g = GaussianSet(parent=rng.integers(0, 4, n), means=rng.normal(size=(n, 3)), quats=rng.normal(size=(n, 4)),
                    log_scales=rng.normal(-3, 1, (n, 3)), opacity_logits=rng.normal(size=n),
                    sh=rng.normal(size=(n, 4, 3)))
    return vertices, faces, g


def test_bound_round_trip_is_exact_and_bakes_world_params(tmp_path):
    from pgc.splats.binding import bind

    vertices, faces, g = _mesh_and_gaussians()
    write_bound_gaussians_ply(tmp_path / "b.ply", g, vertices, faces)
    back = read_bound_gaussians_ply(tmp_path / "b.ply")
    for name in ("parent", "means", "quats", "log_scales", "opacity_logits", "sh"):
        np.testing.assert_array_equal(getattr(back, name), getattr(g, name))
    # the standard columns are what a plain viewer sees: the Gaussians posed on the rest mesh
    world = read_world_gaussians_ply(tmp_path / "b.ply")
    ref = bind(g, vertices, faces)
    np.testing.assert_allclose(world.means, ref.means, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(world.scales, ref.scales, rtol=1e-5)
    np.testing.assert_allclose(world.quats, ref.quats, atol=1e-6)
    np.testing.assert_allclose(world.opacities, ref.opacities, rtol=1e-5)


def test_independent_parser_reads_the_file(tmp_path):
    """trimesh's own PLY parser (an ordinary reader) sees the positions and every property."""
    import trimesh

    g = _random_world(7, 1)
    write_world_gaussians_ply(tmp_path / "t.ply", g)
    cloud = trimesh.load(tmp_path / "t.ply")
    np.testing.assert_allclose(np.asarray(cloud.vertices), g.means, rtol=1e-6, atol=1e-7)
    raw = cloud.metadata["_ply_raw"]["vertex"]["data"]
    np.testing.assert_allclose(raw["rot_3"], g.quats[:, 3], rtol=1e-6, atol=1e-7)


def test_missing_property_names_it_and_the_file(tmp_path):
    header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n" + "".join(
        f"property float {n}\n" for n in ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"]) + "end_header\n"
    (tmp_path / "bad.ply").write_bytes(header.encode() + struct.pack("<6f", *range(6)))
    with pytest.raises(PGCDataError, match=r"bad\.ply: missing PLY properties 'opacity', 'scale_0'"):
        read_world_gaussians_ply(tmp_path / "bad.ply")


def test_plain_file_is_not_a_bound_file(tmp_path):
    write_world_gaussians_ply(tmp_path / "p.ply", _random_world(2, 0))
    with pytest.raises(PGCDataError, match="missing PLY property 'pgc_parent'"):
        read_bound_gaussians_ply(tmp_path / "p.ply")


def test_truncated_and_not_ply(tmp_path):
    write_world_gaussians_ply(tmp_path / "p.ply", _random_world(4, 0))
    data = (tmp_path / "p.ply").read_bytes()
    (tmp_path / "p.ply").write_bytes(data[:-10])
    with pytest.raises(PGCDataError, match="truncated"):
        read_world_gaussians_ply(tmp_path / "p.ply")
    (tmp_path / "n.ply").write_text("hello")
    with pytest.raises(PGCDataError, match="not a PLY file"):
        read_world_gaussians_ply(tmp_path / "n.ply")
