"""The ``smplx`` body model on a tiny SMPL-format model file written here (24 SMPL joints, a tetrahedron of
vertices around each): the smplx package's own loading and skinning run on it and are checked against SMPL's
formula evaluated independently in numpy."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

pytest.importorskip("smplx", reason="the 'smplx' body model needs the smplx package (pip install 'pgc[body]')")
torch = pytest.importorskip("torch", reason="the 'smplx' body model needs torch (pip install 'pgc[body]')")

from pgc.errors import PGCConfigError, PGCDataError  # noqa: E402
from pgc.registry import Registry  # noqa: E402
from pgc.motion.rotations import axis_angle_to_matrix  # noqa: E402
from pgc.roles.body_model import global_transforms  # noqa: E402
from pgc.testing.body_scenes import SMPL_PARENTS, tiny_smpl_arrays  # noqa: E402

def smpl_numpy(data: dict, betas: np.ndarray, rotations: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """SMPL's formula, independently: shape and pose blend shapes, LBS, then PGC's rest placement."""
    data = {k: np.asarray(v, np.float64) for k, v in data.items()}
    shaped = data["v_template"] + data["shapedirs"][..., :len(betas)] @ betas
    joints = data["J_regressor"] @ shaped
    feature = (rotations[1:] - np.eye(3)).reshape(-1)
    posed = shaped + data["posedirs"] @ feature
    G = global_transforms(joints, np.array(SMPL_PARENTS), rotations)
    skinned = np.einsum("vj,jab,vb->va", data["weights"], G[:, :3, :3], posed) + data["weights"] @ G[:, :3, 3]
    ground = np.array([-joints[0, 0], -shaped[:, 1].min(), -joints[0, 2]])
    return skinned + ground + translation


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    data = tiny_smpl_arrays()
    path = tmp_path_factory.mktemp("smpl") / "SMPL_TINY.pkl"
    path.write_bytes(pickle.dumps(data, protocol=2))
    return path, data


@pytest.fixture(scope="module")
def body(tiny):
    return Registry.discover().get("body_model", "smplx").create({"model_path": str(tiny[0])})


def random_pose(rng, J=24, scale=0.6):
    return np.stack([axis_angle_to_matrix(rng.normal(0, scale, 3)) for _ in range(J)])


def test_rig_names_parents_and_rest_placement(body, tiny):
    rig = body.rig()
    assert rig.names[:3] == ("pelvis", "left_hip", "right_hip") and len(rig.names) == 24
    assert rig.names[18:] == ("left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand", "right_hand")
    assert rig.parents.tolist() == SMPL_PARENTS
    rest = body.forward()
    assert rest.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-6)
    assert np.abs(rig.joints[0, [0, 2]]).max() < 1e-6
    assert set(body.parameters) == {f"beta{i}" for i in range(10)}


@pytest.mark.parametrize("seed", [0, 1])
def test_forward_matches_smpl_formula(body, tiny, seed):
    rng = np.random.default_rng(seed)
    betas = rng.uniform(-2, 2, 10)
    rotations, translation = random_pose(rng), rng.normal(0, 0.3, 3)
    state = body.forward({f"beta{i}": b for i, b in enumerate(betas)}, rotations, translation)
    expected = smpl_numpy(tiny[1], betas, rotations, translation)
    # float32 model (smplx's default dtype): error ~ 1e-7 relative on ~1 m coordinates
    np.testing.assert_allclose(state.vertices, expected, atol=2e-6)
    assert state.faces.shape == (96, 3)


def test_float64_forward_and_gradient_match(body, tiny):
    rng = np.random.default_rng(3)
    betas = torch.tensor(rng.uniform(-1, 1, 10), dtype=torch.float64, requires_grad=True)
    rotations = torch.tensor(random_pose(rng)[None])
    translation = torch.zeros(1, 3, dtype=torch.float64)

    def f(b):
        return body.forward_torch({f"beta{i}": b[i:i + 1] for i in range(10)}, rotations, translation).vertices

    out = f(betas)
    expected = smpl_numpy(tiny[1], betas.detach().numpy(), rotations[0].numpy(), np.zeros(3))
    np.testing.assert_allclose(out[0].detach().numpy(), expected, atol=1e-12)
    weights = torch.tensor(rng.normal(size=out.shape))
    (out * weights).sum().backward()
    h = 1e-6
    with torch.no_grad():
        numeric = [((f(betas + h * e) - f(betas - h * e)) * weights).sum().item() / (2 * h)
                   for e in torch.eye(10, dtype=torch.float64)[[0, 4, 9]]]
    np.testing.assert_allclose(betas.grad.numpy()[[0, 4, 9]], numeric, rtol=1e-6, atol=1e-9)


def test_skin_clip_equals_per_frame_forward(body):
    rng = np.random.default_rng(5)
    rotations = np.stack([random_pose(rng) for _ in range(5)])
    translation = rng.normal(0, 0.1, (5, 3))
    clip = body.skin({"beta1": 0.5}, rotations, translation, chunk=2)
    assert clip.shape == (5, 96, 3) and clip.dtype == np.float32
    for t in (0, 4):
        np.testing.assert_allclose(clip[t], body.forward({"beta1": 0.5}, rotations[t], translation[t]).vertices,
                                   atol=1e-6)


def test_npz_file_gives_the_same_body(tiny, tmp_path, body):
    path = tmp_path / "SMPL_TINY.npz"
    np.savez(path, **tiny[1])
    other = Registry.discover().get("body_model", "smplx").create({"model_path": str(path)})
    np.testing.assert_array_equal(other.forward().vertices, body.forward().vertices)


class _Foreign:
    """Stands for a chumpy array inside an unconverted SMPL pickle."""


def test_bad_model_files_get_one_clear_error(tmp_path, tiny):
    impl = Registry.discover().get("body_model", "smplx")
    with pytest.raises(PGCConfigError, match="model_path"):
        impl.create({})
    cases = {"missing.pkl": None, "text.pkl": b"not a pickle", "foreign.pkl": pickle.dumps({"f": _Foreign()})}
    lacking = dict(tiny[1])
    del lacking["posedirs"]
    cases["lacking.pkl"] = pickle.dumps(lacking)
    bad_shape = dict(tiny[1], weights=tiny[1]["weights"][:, :5])
    cases["bad_shape.pkl"] = pickle.dumps(bad_shape)
    for name, content in cases.items():
        if content is not None:
            (tmp_path / name).write_bytes(content)
        with pytest.raises(PGCDataError, match="model_path") as err:
            impl.create({"model_path": str(tmp_path / name)})
        assert "SMPL" in str(err.value), name
    with pytest.raises(PGCDataError, match="lacks \\['posedirs'\\]"):
        impl.create({"model_path": str(tmp_path / "lacking.pkl")})
    with pytest.raises(PGCDataError, match="_Foreign"):
        impl.create({"model_path": str(tmp_path / "foreign.pkl")})


def test_bad_shape_and_pose_inputs(body):
    with pytest.raises(PGCDataError, match="unknown shape parameter.*'height'"):
        body.forward({"height": 1.0})
    with pytest.raises(PGCDataError, match=r"beta0' = 4.0 is outside its range \[-3.0, 3.0\]"):
        body.forward({"beta0": 4.0})
    with pytest.raises(PGCDataError, match="finite number"):
        body.forward({"beta0": float("nan")})
    with pytest.raises(PGCDataError, match=r"rotations must have shape \(24, 3, 3\)"):
        body.forward(None, np.eye(3)[None].repeat(23, 0))
    with pytest.raises(PGCDataError, match="proper rotation"):
        body.forward(None, 2 * np.eye(3)[None].repeat(24, 0))
