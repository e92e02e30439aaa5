"""Mesh files: OBJ keeps UV seams and labels, PLY keeps labels, glTF round trips; bad files fail clearly."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.errors import PGCDataError
from pgc.io.mesh import read_mesh, write_mesh
from pgc.types import Mesh


def _corner_uvs(m: Mesh) -> np.ndarray:
    return m.uv[m.face_uv]


def _corner_positions(m: Mesh) -> np.ndarray:
    return m.vertices[m.faces]


def test_obj_round_trip_keeps_seams_labels_and_exact_positions(tmp_path):
    m = seamed_cube()
    write_mesh(tmp_path / "c.obj", m)
    back = read_mesh(tmp_path / "c.obj")
    np.testing.assert_array_equal(back.vertices, m.vertices)  # %.17g: exact float64
    np.testing.assert_array_equal(back.faces, m.faces)
    np.testing.assert_array_equal(back.face_uv, m.face_uv)
    np.testing.assert_allclose(back.uv, m.uv, atol=1e-7)
    np.testing.assert_array_equal(back.face_labels, m.face_labels)
    assert len(back.vertices) == 8 and len(back.uv) == 24 and back.name == "c"


def test_obj_from_another_tool(tmp_path):
    """Quads, negative indices, normals in the face tokens, no labels."""
    (tmp_path / "q.obj").write_text("o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                                    "vt 0 1\nvn 0 0 1\nf -4/-4/1 -3/-3/1 -2/-2/1 -1/-1/1\n")
    m = read_mesh(tmp_path / "q.obj")
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(m.face_uv, [[0, 1, 2], [0, 2, 3]])
    assert m.face_labels is None
    np.testing.assert_allclose(m.face_normals(), [[0, 0, 1], [0, 0, 1]])


def test_ply_round_trip_with_labels(tmp_path):
    m = seamed_cube()
    write_mesh(tmp_path / "c.ply", m)
    back = read_mesh(tmp_path / "c.ply")
    np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-6)  # float32 positions
    np.testing.assert_array_equal(back.faces, m.faces)
    np.testing.assert_array_equal(back.face_labels, m.face_labels)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_round_trip_welds_seams(tmp_path, suffix):
    m = seamed_cube()
    write_mesh(tmp_path / f"c{suffix}", m)
    back = read_mesh(tmp_path / f"c{suffix}")
    assert len(back.vertices) == 8 and len(back.faces) == 12
    # the same triangles, corner by corner, with the same UVs
    order_a = np.lexsort(np.round(_corner_positions(m), 5).reshape(12, -1).T)
    order_b = np.lexsort(np.round(_corner_positions(back), 5).reshape(12, -1).T)
    np.testing.assert_allclose(_corner_positions(back)[order_b], _corner_positions(m)[order_a], atol=1e-6)
    np.testing.assert_allclose(_corner_uvs(back)[order_b], _corner_uvs(m)[order_a], atol=1e-6)
    np.testing.assert_array_equal(back.face_labels[order_b], m.face_labels[order_a])


def test_nan_in_mesh_names_the_file(tmp_path):
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(PGCDataError, match=r"nan\.obj: mesh 'nan': field 'vertices' has 1 non-finite"):
        read_mesh(tmp_path / "nan.obj")


def test_bad_mesh_files(tmp_path):
    (tmp_path / "idx.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    with pytest.raises(PGCDataError, match=r"idx\.obj:4: vertex index 4 out of range \(1\.\.3\)"):
        read_mesh(tmp_path / "idx.obj")
    (tmp_path / "pts.obj").write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(PGCDataError, match=r"pts\.obj: no faces"):
        read_mesh(tmp_path / "pts.obj")
    (tmp_path / "junk.ply").write_text("this is not a ply file")
    with pytest.raises(PGCDataError, match=r"junk\.ply: "):
        read_mesh(tmp_path / "junk.ply")
    with pytest.raises(PGCDataError, match=r"missing\.obj: file not found"):
        read_mesh(tmp_path / "missing.obj")
    with pytest.raises(PGCDataError, match=r"unsupported mesh type '\.stl'"):
        write_mesh(tmp_path / "x.stl", seamed_cube())
