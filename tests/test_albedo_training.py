"""The albedo training script: seeded runs reproduce the same network; the shipped model's record holds."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_smoke_training_is_reproducible_and_its_record_finite(tmp_path):
    pytest.importorskip("onnx", reason="export needs onnx (pgc[train])")
    import onnx
    from onnx import numpy_helper

    outs = []
    for k in range(2):
        out = tmp_path / f"m{k}.onnx"
        subprocess.run([sys.executable, str(ROOT / "scripts" / "train_albedo.py"), "--smoke", "--out", str(out)],
                       check=True, capture_output=True)
        outs.append(out)
    w0, w1 = ([numpy_helper.to_array(t) for t in onnx.load(str(p)).graph.initializer] for p in outs)
    assert len(w0) == len(w1) > 0
    for a, b in zip(w0, w1):
        np.testing.assert_array_equal(a, b)
    record = json.loads(outs[0].with_suffix(".json").read_text())
    assert np.isfinite(record["validation"]["albedo_error"])


def test_shipped_model_matches_its_record():
    import hashlib

    model = ROOT / "plugins" / "pgc_onnx" / "models" / "albedo_unet.onnx"
    record = json.loads(model.with_suffix(".json").read_text())
    assert hashlib.sha256(model.read_bytes()).hexdigest() == record["sha256"]
    assert record["data"]["validation"]["garment"] == "dress" != record["data"]["train"]["garment"]
    assert record["data"]["data_version"] == 3  # trained on the Anny-body renders of pgc.synth.albedo_data


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="a known regression, measured 2026-12-03: on the Anny-body captures the "
                                       "retrained network (validation error 0.0192 against the raw image's 0.0197) "
                                       "loses on this held-out dress (0.0166 against 0.0118); see docs/albedo.md")
def test_shipped_model_beats_the_raw_image_on_a_held_out_garment(default_scene_renderer, default_body_model):
    pytest.importorskip("onnxruntime", reason="the onnx estimator needs onnxruntime (pgc[onnx])")
    from pgc.synth.albedo_data import make_albedo_data
    from pgc_onnx.albedo import OnnxAlbedoEstimator
    from pgc_torch.albedo.train import evaluate

    model = ROOT / "plugins" / "pgc_onnx" / "models" / "albedo_unet.onnx"
    record = json.loads(model.with_suffix(".json").read_text())
    # a fresh scene of the garment the network never saw (a seed outside the training and validation sets)
    data = make_albedo_data("dress", scenes=1, views=3, resolution=record["data"]["resolution"], seed=777,
                            renderer=default_scene_renderer, body_model=default_body_model)
    scores = evaluate(OnnxAlbedoEstimator().estimate, data)
    assert scores["albedo_error"] < scores["raw_image_error"]
