"""Loading body motions: npz and OBJ folders, with clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.io.motion import load_motion
from pgc.testing.cloth_scenes import uv_sphere


def _frames(n: int = 3) -> tuple[np.ndarray, np.ndarray]:
    body = uv_sphere(0.2, rings=4, segments=6)
    return np.stack([body.vertices + [0.01 * t, 0, 0] for t in range(n)]), body.faces


def test_npz_round_trip_with_fps(tmp_path):
    v, f = _frames()
    np.savez(tmp_path / "walk.npz", vertices=v, faces=f, fps=24.0)
    m = load_motion(tmp_path / "walk.npz")
    assert m.num_frames == 3 and m.fps == 24.0 and m.name == "walk"
    np.testing.assert_allclose(m.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(m.faces, f)
    assert load_motion(tmp_path / "walk.npz", fps=60.0).fps == 60.0


def test_obj_folder_in_natural_order(tmp_path):
    v, f = _frames(11)
    for t in range(11):
        lines = [f"v {x} {y} {z}" for x, y, z in v[t]] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
        (tmp_path / f"frame_{t}.obj").write_text("\n".join(lines))
    m = load_motion(tmp_path, fps=30.0)
    assert m.num_frames == 11
    np.testing.assert_allclose(m.vertices[:, 0, 0], v[:, 0, 0], atol=1e-6)  # frame_10 after frame_9


@pytest.mark.parametrize("case", ["missing_faces", "bad_shape", "bad_index", "missing_file", "empty_dir", "topology"])
def test_bad_motion_files_name_the_problem(tmp_path, case):
    v, f = _frames()
    path = tmp_path / "m.npz"
    if case == "missing_faces":
        np.savez(path, vertices=v)
    elif case == "bad_shape":
        np.savez(path, vertices=v[0], faces=f)
    elif case == "bad_index":
        np.savez(path, vertices=v, faces=f + 1000)
    elif case == "missing_file":
        path = tmp_path / "nothing.npz"
    elif case == "empty_dir":
        path = tmp_path
    else:
        (tmp_path / "a1.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        (tmp_path / "a2.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
        path = tmp_path
    with pytest.raises(PGCDataError, match=str(path.name) if case != "topology" else "a2.obj"):
        load_motion(path)
