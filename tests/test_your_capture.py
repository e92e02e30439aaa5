"""A capture without ground truth, end to end (docs/your-capture.md): reconstruct (with the body fit) -> animate
with a captured clip on the fitted body -> render -> report; and the clear errors on the way."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from conftest import SHORT_SIMULATION
from pgc.cli import main
from pgc.io.body_fit import BODY_FIT_DIR, read_body_fit
from pgc.testing.capture_scenes import strip_ground_truth

FAST = SHORT_SIMULATION + """
[stages.body_fit]
iterations = 60
views = 4
"""
"""A shorter simulation and body fit than the tiny demo's (the end-to-end test checks that they run and are used;
tests/test_body_fit.py, what the fit recovers)."""


@pytest.fixture(scope="module")
def own_capture(tiny_demo, tmp_path_factory) -> Path:
    """The tiny demo's capture stripped of everything the generator knows."""
    return strip_ground_truth(tiny_demo / "capture", tmp_path_factory.mktemp("own") / "capture")


@pytest.fixture(scope="module")
def config(tmp_path_factory) -> Path:
    from importlib import resources

    path = tmp_path_factory.mktemp("own_config") / "config.toml"
    path.write_text((resources.files("pgc") / "presets" / "demo_tiny.toml").read_text() + FAST)
    return path


def test_stripped_capture_holds_no_truth(own_capture):
    names = {p.name for p in own_capture.iterdir()}
    assert {"transforms.json", "images", "masks", "segmentation"} <= names
    assert not names & {"ground_truth", "extras", "light"}
    doc = json.loads((own_capture / "transforms.json").read_text())
    assert "pgc_metadata" not in doc and "pgc_light" not in doc
    assert all("pgc_extras" not in f for f in doc["frames"])


@pytest.mark.slow
def test_reconstruct_fit_animate_render_report_without_ground_truth(own_capture, config, tmp_path):
    asset, run = tmp_path / "asset", tmp_path / "walk"
    assert main(["reconstruct", str(own_capture), "--out", str(asset), "--config", str(config), "--quiet"]) == 0
    fit = read_body_fit(asset / BODY_FIT_DIR)  # the body fit ran: the capture brings no body
    assert fit.model == "anny" and np.isfinite(fit.mesh.vertices).all()
    assert main(["animate", str(asset), "--motion", "cmu:02_01", "--out", str(run), "--config", str(config),
                 "--quiet"]) == 0
    body = np.load(run / "body.npz")["vertices"]
    # the clip starts on the fitted body; only the upper arms may be turned out (keep_arms_clear) where the fitted
    # arms hang closer to the chest than the arm space
    from pgc.pipeline.motion_source import fitted_body

    skinned = fitted_body(asset / BODY_FIT_DIR)
    arms = {skinned.joint_names.index(n) for n in ("LeftArm", "RightArm")}
    for j, p in enumerate(skinned.parents):
        if p in arms:
            arms.add(j)
    still = skinned.weights[:, sorted(arms)].sum(axis=1) < 1e-6
    assert still.mean() > 0.5
    np.testing.assert_allclose(body[0][still], fit.mesh.vertices[still], atol=1e-4)
    assert np.abs(body[-1] - body[0]).max() > 0.02  # and moves it
    garment = np.load(run / "garment.npz")["vertices"]
    assert np.isfinite(garment).all() and len(garment) == len(body)
    assert main(["render", str(run), "--config", str(config), "--quiet"]) == 0
    assert main(["report", str(run)]) == 0
    assert (run / "report.html").is_file() and any((run / "render").iterdir())


def test_a_clip_without_any_body_is_one_clear_error(own_capture, tmp_path, capsys):
    """An asset whose capture has no truth and that holds no fitted body: the message says what to do."""
    from pgc.pipeline.motion_source import capture_body

    with pytest.raises(Exception, match=r"needs the capture's body.*ASSET/body_fit"):
        capture_body(own_capture, tmp_path / "no_body_fit", "clip 'cmu:02_01'")


def test_a_capture_without_labels_is_refused_before_any_work(own_capture, tmp_path, capsys):
    bare = tmp_path / "bare"
    shutil.copytree(own_capture, bare)
    shutil.rmtree(bare / "segmentation")
    doc = json.loads((bare / "transforms.json").read_text())
    for frame in doc["frames"]:
        frame.pop("pgc_segmentation_path", None)
    (bare / "transforms.json").write_text(json.dumps(doc))
    assert main(["reconstruct", str(bare), "--out", str(tmp_path / "asset"), "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "needs segmentation labels for every view" in err and "pgc_segmentation_path" in err
    assert "Traceback" not in err and not (tmp_path / "asset" / "stages").exists()  # refused before any stage
