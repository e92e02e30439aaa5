"""Which body a run moves on (pgc.pipeline.motion_source): the rule, ``[stages.body_fit] motion_body`` and
``pgc reconstruct --body``, what run.json records, the independent truth's motion made again on the true body's
rig, and appearance mode's refusal of a run on the fitted body.

The scene is a coarse synthetic t-shirt on the default body model, its capture holding only the true body, and an
asset that moves on a fitted body: the same model, thinner and shorter, written as ``ASSET/body_fit``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pgc.cli import main
from pgc.errors import PGCConfigError, PGCDataError
from pgc.motion.drive import ClipOptions
from pgc.testing.cloth_scenes import QUICK_ANIMATE_CONFIG

CLIP, IN_PLACE = "cmu:02_01", ClipOptions(in_place=True)


@pytest.fixture(scope="module")
def scene(tmp_path_factory, default_body_model) -> Path:
    """``capture`` (its ground truth: the true body only), ``asset-truth`` (moves on it) and ``asset-fit`` (moves
    on ``body_fit``: the body model thinner and shorter, in the capture pose), ``config.toml``."""
    from pgc.body.fit import BodyFit
    from pgc.io.asset import write_asset
    from pgc.io.body_fit import write_body_fit
    from pgc.synth.body import make_body
    from pgc.synth.garments import make_garment
    from pgc.synth.ground_truth import write_body_model
    from pgc.types import GarmentAsset, GaussianSet, Light, Material, Mesh

    root = tmp_path_factory.mktemp("independent_body")
    body = make_body(default_body_model)
    (root / "capture" / "ground_truth").mkdir(parents=True)
    write_body_model(root / "capture" / "ground_truth", body)
    garment = make_garment(body, "tshirt", resolution=0.05)
    rng = np.random.default_rng(0)
    n = 8
    gaussians = GaussianSet(parent=rng.integers(0, len(garment.faces), n), means=rng.normal(size=(n, 3)) * 0.01,
                            quats=rng.normal(size=(n, 4)), log_scales=np.full((n, 3), -5.0),
                            opacity_logits=np.zeros(n), sh=rng.random((n, 1, 3)))
    for kind in ("truth", "fit"):
        write_asset(root / f"asset-{kind}", GarmentAsset(
            garment=garment, body=body.mesh(), gaussians=gaussians,
            material=Material("lambertian", {}, np.full((8, 8, 3), 0.5, np.float32)), light=Light(radiance=np.ones(3)),
            config={"source": {"capture": str(root / "capture"), "body": kind}}, figures={}))
    shape = dict(body.phenotype, weight=max(0.0, body.phenotype["weight"] - 0.2),
                 height=max(0.0, body.phenotype["height"] - 0.1))
    posed = default_body_model.forward(shape)
    joints = len(default_body_model.joint_names)
    write_body_fit(root / "asset-fit" / "body_fit", BodyFit(
        "anny", dict(default_body_model.options.model_dump()), shape, tuple(default_body_model.joint_names),
        np.tile(np.eye(3), (joints, 1, 1)), np.zeros(3), Mesh(posed.vertices, posed.faces), {}))
    (root / "config.toml").write_text(QUICK_ANIMATE_CONFIG)
    return root


@pytest.fixture(scope="module")
def runs(scene) -> dict[str, Path]:
    """The shipped walk clip (in place) animated on each asset."""
    from pgc.config import load
    from pgc.pipeline.animate import animate

    cfg = load(scene / "config.toml")
    return {kind: animate(scene / f"asset-{kind}", CLIP, scene / f"run-{kind}", cfg, clip=IN_PLACE)
            for kind in ("truth", "fit")}


def test_the_rule_moves_the_true_body_unless_the_fit_is_asked_for_or_there_is_no_truth(scene, tmp_path):
    from pgc.pipeline.motion_source import has_body_truth, motion_body

    capture, bare = scene / "capture", tmp_path / "own-capture"
    bare.mkdir()
    assert has_body_truth(capture) and not has_body_truth(bare) and not has_body_truth(None)
    assert motion_body(capture, "truth") == "truth" and motion_body(capture, "fit") == "fit"
    assert motion_body(bare, "truth") == "fit" and motion_body(bare, "fit") == "fit"
    with pytest.raises(PGCDataError, match="motion body 'both' is unknown; use one of: truth, fit"):
        motion_body(capture, "both")


def test_the_config_setting_and_the_reconstruct_flag(tmp_path, capsys):
    from pgc.config import load
    from pgc.pipeline.motion_source import with_motion_body

    cfg = load()
    assert cfg.stage("body_fit").motion_body == "truth"
    fit = with_motion_body(cfg, "fit")
    assert fit.stage("body_fit").motion_body == "fit" and cfg.stage("body_fit").motion_body == "truth"
    assert fit.stage("body_fit").iterations == cfg.stage("body_fit").iterations
    assert fit.to_dict()["stages"]["body_fit"]["motion_body"] == "fit"
    (tmp_path / "bad.toml").write_text('[stages.body_fit]\nmotion_body = "both"\n')
    with pytest.raises(PGCConfigError, match="motion_body") as exc:
        load(tmp_path / "bad.toml")
    assert "'truth' or 'fit'" in str(exc.value)
    with pytest.raises(SystemExit) as stop:
        main(["reconstruct", "CAPTURE", "--out", str(tmp_path / "asset"), "--body", "both"])
    assert stop.value.code == 2 and "argument --body: invalid choice: 'both'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reconstruct", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--body {truth,fit}" in text and "[stages.body_fit] motion_body" in text
    assert "pgc eval --mode independent" in text


def test_an_asset_moves_on_the_body_it_recorded_and_an_older_one_by_the_rule(scene, tmp_path):
    from pgc.pipeline.motion_source import asset_body

    capture, bare = scene / "capture", tmp_path / "own-capture"
    bare.mkdir()
    assert asset_body({"source": {"body": "fit"}}, capture) == "fit"
    assert asset_body({"source": {"body": "truth"}}, capture) == "truth"
    assert asset_body({"source": {"capture": str(capture)}}, capture) == "truth"  # recorded before bodies were
    assert asset_body({}, bare) == "fit"


def test_run_json_records_the_body_and_the_motion_source(runs, scene):
    for kind, run in runs.items():
        meta = json.loads((run / "run.json").read_text())
        assert meta["body"] == kind and meta["motion"] == CLIP
        assert meta["motion_source"] == {"spec": CLIP, "kind": "clip", "seconds": 0.4,
                                         "clip": {"skeleton": None, "fps": None, "unit_m": None, "joint_map": None,
                                                  "in_place": True}}


def test_a_run_on_the_fitted_body_moves_that_body(runs, scene):
    from pgc.io.body_fit import read_body_fit
    from pgc.synth.ground_truth import read_body_model

    fitted = read_body_fit(scene / "asset-fit" / "body_fit").mesh.vertices
    true = read_body_model(scene / "capture").vertices
    truth_run, fit_run = (np.load(runs[k] / "body.npz")["vertices"] for k in ("truth", "fit"))
    assert np.abs(fitted - true).max() > 0.01  # the fitted body is another body
    np.testing.assert_allclose(fit_run[0], fitted, atol=1e-4)  # frame 0: the fitted capture pose
    np.testing.assert_allclose(truth_run[0], true, atol=1e-4)
    assert len(fit_run) == len(truth_run) and np.abs(fit_run[-1] - fit_run[0]).max() > 0.02


def test_the_truth_moves_on_the_true_rig_by_the_runs_clip_whichever_body_the_run_moved(runs, scene):
    from pgc.pipeline.independent import truth_body_motion

    truth_run = np.load(runs["truth"] / "body.npz")["vertices"]
    for run in runs.values():
        motion = truth_body_motion(run, scene / "capture")
        assert motion.fps == 30.0 and motion.vertices.shape == truth_run.shape
        np.testing.assert_allclose(motion.vertices, truth_run, atol=1e-5)  # the run's clip frames, on the true body
    fit_run = np.load(runs["fit"] / "body.npz")["vertices"]
    assert np.abs(fit_run - truth_run).max() > 0.01


def test_the_truth_motion_refuses_a_run_whose_frames_its_clip_does_not_give(runs, scene, tmp_path):
    from pgc.pipeline.independent import truth_body_motion

    run = tmp_path / "run"
    shutil.copytree(runs["fit"], run)
    meta = json.loads((run / "run.json").read_text())
    meta["motion_source"]["seconds"] = 0.2
    (run / "run.json").write_text(json.dumps(meta))
    with pytest.raises(PGCDataError, match=r"on the capture's true body gives 7 frames at 30 fps, the run has 13"):
        truth_body_motion(run, scene / "capture")
    meta["motion_source"] = {"spec": CLIP}
    (run / "run.json").write_text(json.dumps(meta))
    with pytest.raises(PGCDataError, match="field 'motion_source' must hold 'spec' and 'clip'"):
        truth_body_motion(run, scene / "capture")


def test_a_motion_file_run_must_have_moved_the_true_body(runs, scene, tmp_path):
    """A run on a motion file of body vertices moved on those vertices: the truth takes them when they are the
    true body's, and refuses another body's."""
    from pgc.pipeline.independent import truth_body_motion

    run = tmp_path / "run"
    shutil.copytree(runs["truth"], run)
    meta = json.loads((run / "run.json").read_text())
    meta.update(body=None, motion_source=dict(meta["motion_source"], kind="file"))
    (run / "run.json").write_text(json.dumps(meta))
    np.testing.assert_array_equal(truth_body_motion(run, scene / "capture").vertices,
                                  np.load(run / "body.npz")["vertices"])
    z = dict(np.load(run / "body.npz"))
    np.savez(run / "body.npz", vertices=z["vertices"][:, :100], faces=z["faces"][:10])
    with pytest.raises(PGCDataError, match=r"moved on a motion file of 100 body vertices.*true body has"):
        truth_body_motion(run, scene / "capture")


def test_appearance_mode_refuses_a_run_on_the_fitted_body_with_one_clear_error(runs, scene, tmp_path):
    from pgc.config import load
    from pgc.pipeline.evaluate import evaluate_run

    cfg = load(scene / "config.toml")
    with pytest.raises(PGCDataError) as exc:
        evaluate_run(runs["fit"], scene / "capture", cfg, mode="appearance")
    text = str(exc.value)
    assert "moved on the body fitted to the capture" in text and "--mode independent" in text
    assert "pgc reconstruct --body truth" in text and "\n" not in text
    images = tmp_path / "images"  # a folder of truth images is the user's own truth: not refused for the body
    images.mkdir()
    with pytest.raises(PGCDataError, match="no rendered frames"):
        evaluate_run(runs["fit"], images, cfg, mode="appearance")
    with pytest.raises(PGCDataError, match="no rendered frames"):  # the truth run passes the body check
        evaluate_run(runs["truth"], scene / "capture", cfg, mode="appearance")
