"""The ``body_model`` role: registration, the contract every available implementation keeps (``anny`` and
``smplx`` on a tiny SMPL-format file), and Anny's body: a plausible human, the CMU rig, skinning, gradients."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pgc.errors import PGCConfigError, PGCDataError, PGCPluginError
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.registry import ROLES, Registry
from pgc.testing.conformance import BodyModelConformance

REGISTRY = Registry.discover()
HAVE_ANNY = REGISTRY.get("body_model", "anny").available
HAVE_SMPLX = REGISTRY.get("body_model", "smplx").available
needs_anny = pytest.mark.skipif(not HAVE_ANNY, reason="the 'anny' body model needs the anny package "
                                                      "(pip install 'pgc[body]'; scripts/setup.sh installs it)")

CMU_ASF_HIERARCHY = """root lhipjoint rhipjoint lowerback
lhipjoint lfemur
lfemur ltibia
ltibia lfoot
lfoot ltoes
rhipjoint rfemur
rfemur rtibia
rtibia rfoot
rfoot rtoes
lowerback upperback
upperback thorax
thorax lowerneck lclavicle rclavicle
lowerneck upperneck
upperneck head
lclavicle lhumerus
lhumerus lradius
lradius lwrist
lwrist lhand lthumb
lhand lfingers
rclavicle rhumerus
rhumerus rradius
rradius rwrist
rwrist rhand rthumb
rhand rfingers"""
"""The ':hierarchy' section of every CMU motion-capture subject's .asf file."""


def test_role_is_registered_with_both_implementations():
    assert ROLES["body_model"] == "pgc.roles.body_model:BodyModel"
    names = {i.name for i in REGISTRY.list("body_model")}
    assert {"anny", "smplx"} <= names
    assert REGISTRY.get("body_model", "anny").spec.requires[0] == "anny"
    assert REGISTRY.get("body_model", "smplx").spec.requires[0] == "smplx"


def test_default_config_chooses_anny():
    from pgc.config import load

    choice = load(None).roles["body_model"]
    assert choice.requested == ["anny"] and (choice.name == "anny" or not HAVE_ANNY)


def test_missing_package_gives_the_registry_message():
    spec = dataclasses.replace(REGISTRY.get("body_model", "anny").spec, requires=("anny_not_installed_here",))
    registry = Registry()
    registry.add(spec)
    assert not registry.get("body_model", "anny").available
    with pytest.raises(PGCPluginError, match=r"anny_not_installed_here.*pip install 'pgc\[body\]'"):
        registry.create("body_model", "anny")


@pytest.fixture(scope="module")
def tiny_smpl_file(tmp_path_factory):
    from pgc.testing.body_scenes import write_tiny_smpl

    return write_tiny_smpl(tmp_path_factory.mktemp("smpl") / "SMPL_TINY.pkl")


@pytest.fixture(scope="module")
def anny_body():
    if not HAVE_ANNY:
        pytest.skip("the 'anny' body model needs the anny package (pip install 'pgc[body]')")
    return REGISTRY.get("body_model", "anny").create()


IMPLEMENTATIONS = [pytest.param("anny", marks=needs_anny),
                   pytest.param("smplx", marks=pytest.mark.skipif(not HAVE_SMPLX, reason="needs smplx"))]


@pytest.fixture(params=IMPLEMENTATIONS)
def body(request, tiny_smpl_file, anny_body):
    if request.param == "anny":
        return anny_body
    return REGISTRY.get("body_model", "smplx").create({"model_path": str(tiny_smpl_file)})


class TestBodyModelImplementations(BodyModelConformance):
    @pytest.fixture
    def implementation(self, body):
        return body


def random_rotations(rng, J, scale=0.5):
    return np.stack([axis_angle_to_matrix(rng.normal(0, scale, 3)) for _ in range(J)])


# Anny's body --------------------------------------------------------------------------------------------------

@needs_anny
def test_anny_is_a_plausible_adult(anny_body):
    rest = anny_body.forward()
    v = rest.vertices
    height = v[:, 1].max()
    assert 1.55 < height < 2.0  # an average adult of neutral gender (MakeHuman's 'young' age target)
    lo, hi = v.min(axis=0), v.max(axis=0)
    assert np.all((rest.joints >= lo) & (rest.joints <= hi))
    assert 0.3 < (hi - lo)[0] / height < 0.8  # arms in the A-pose
    names = anny_body.joint_names
    j = dict(zip(names, rest.joints))
    assert j["LeftUpLeg"][0] > 0.05 and j["RightUpLeg"][0] < -0.05  # the person's left is +X
    assert j["LeftToeBase"][2] > j["LeftFoot"][2] + 0.05  # facing +Z
    assert j["Head"][1] > j["Neck"][1] > j["Spine1"][1] > j["Hips"][1] > j["LeftLeg"][1] > j["LeftFoot"][1]
    # closed 2-manifold surface (cloth collision needs an inside)
    f = rest.faces
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)


@needs_anny
def test_anny_phenotypes_change_the_body_as_named(anny_body):
    def size(**shape):
        """Height (m) and volume (litres)."""
        state = anny_body.forward(shape)
        v, f = state.vertices, state.faces
        return v[:, 1].max(), np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6e-3

    short, tall = size(height=0.0), size(height=1.0)
    assert 1.0 < short[0] < size()[0] < tall[0] < 2.5
    assert 50 < size()[1] < 100  # litres: an adult's volume, about its mass in kg
    assert size(weight=1.0)[1] > 1.15 * size(weight=0.0)[1]
    assert size(gender=0.0)[0] > size(gender=1.0)[0] + 0.05  # men are taller
    assert size(age=1 / 3)[0] < size()[0] - 0.2  # a child is shorter than an adult
    with pytest.raises(PGCDataError, match=r"'age' = -0.1 is outside its range \[0.0, 1.0\]"):
        anny_body.forward({"age": -0.1})


@needs_anny
def test_anny_rig_is_cmu_asf_skeleton(anny_body):
    from pgc.body.anny import CMU_ASF_JOINTS

    names, parents = anny_body.joint_names, anny_body.parents
    assert len(names) == 31 and set(CMU_ASF_JOINTS.values()) == set(names)
    for line in CMU_ASF_HIERARCHY.splitlines():
        parent, *children = line.split()
        for child in children:
            assert names[parents[names.index(CMU_ASF_JOINTS[child])]] == CMU_ASF_JOINTS[parent], child


@needs_anny
def test_anny_elbow_moves_only_the_forearm_side(anny_body):
    names = anny_body.joint_names
    rest = anny_body.forward()
    rotations = np.broadcast_to(np.eye(3), (len(names), 3, 3)).copy()
    rotations[names.index("LeftForeArm")] = axis_angle_to_matrix(np.array([0.0, 0.0, np.pi / 2]))
    bent = anny_body.forward(None, rotations)
    moved = np.linalg.norm(bent.vertices - rest.vertices, axis=1)
    elbow = rest.joints[names.index("LeftForeArm")]
    assert moved[rest.vertices[:, 0] < 0.05].max() < 1e-12  # the right half and the middle stay
    assert moved[rest.vertices[:, 0] < elbow[0] - 0.1].max() < 1e-12  # nothing above the upper arm's middle
    hand = rest.vertices[:, 0] > rest.joints[names.index("LeftHand")][0]
    assert moved[hand].min() > 0.15
    forearm_joints = [names.index(n) for n in ("LeftHand", "LThumb", "LeftFingerBase", "LeftHandFinger1")]
    radius = np.linalg.norm(rest.joints[forearm_joints] - elbow, axis=1)
    np.testing.assert_allclose(np.linalg.norm(bent.joints[forearm_joints] - elbow, axis=1), radius, atol=1e-9)


@needs_anny
def test_anny_float32_agrees_with_float64(anny_body):
    import torch

    rng = np.random.default_rng(6)
    rotations = random_rotations(rng, len(anny_body.joint_names), 0.4)[None]
    shape = anny_body.check_shape({"weight": 0.8})

    def run(dtype):
        out = anny_body.forward_torch({k: torch.tensor([v], dtype=dtype) for k, v in shape.items()},
                                      torch.tensor(rotations, dtype=dtype), torch.zeros(1, 3, dtype=dtype))
        assert out.vertices.dtype == dtype
        return out.vertices.double().numpy()

    assert np.abs(run(torch.float32) - run(torch.float64)).max() < 1e-5  # metres


@needs_anny
def test_anny_never_downloads(monkeypatch):
    import socket

    from pgc.body import anny

    def refuse(*args, **kwargs):
        raise AssertionError("the anny body model tried to open a network connection")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    anny.build_anny.cache_clear()
    try:
        body = REGISTRY.get("body_model", "anny").create()
        assert np.all(np.isfinite(body.skin({"gender": 0.2}, np.broadcast_to(np.eye(3), (2, 31, 3, 3)))))
    finally:
        anny.build_anny.cache_clear()


def test_anny_options_are_validated():
    impl = REGISTRY.get("body_model", "anny")
    with pytest.raises(PGCConfigError, match="topology"):
        impl.validate_options({"topology": "huge"})
    with pytest.raises(PGCConfigError, match="rig"):
        impl.validate_options({"rig": "mixamo"})


@needs_anny
def test_prepare_builds_the_default_topology(anny_body, capsys):
    from pgc.body.prepare import main

    assert main([]) == 0
    err = capsys.readouterr().err
    assert "[anny] notoes_collapse10pc: 1229 vertices, 31 joints, built in" in err and "MB" in err
