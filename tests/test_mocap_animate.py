"""``pgc animate`` with a shipped CMU clip on a coarse synthetic body and t-shirt, end to end (slow)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from pgc.cli import main
from pgc.io.lock import LOCK_NAME
from pgc.testing.cloth_scenes import QUICK_ANIMATE_CONFIG



@pytest.fixture(scope="module")
def scene(tmp_path_factory, default_body_model) -> Path:
    """An asset (a coarse fitted t-shirt on the synthetic body) and the capture holding that body's model."""
    from pgc.io.asset import write_asset
    from pgc.synth.body import make_body
    from pgc.synth.garments import make_garment
    from pgc.synth.ground_truth import write_body_model
    from pgc.types import GarmentAsset, GaussianSet, Light, Material

    root = tmp_path_factory.mktemp("mocap_scene")
    body = make_body(default_body_model)
    garment = make_garment(body, "tshirt", resolution=0.05)
    rng = np.random.default_rng(0)
    n = 8
    gaussians = GaussianSet(parent=rng.integers(0, len(garment.faces), n), means=rng.normal(size=(n, 3)) * 0.01,
                            quats=rng.normal(size=(n, 4)), log_scales=np.full((n, 3), -5.0),
                            opacity_logits=np.zeros(n), sh=rng.random((n, 1, 3)))
    write_asset(root / "asset", GarmentAsset(garment=garment, body=body.mesh(), gaussians=gaussians,
                                             material=Material("lambertian", {}, np.full((8, 8, 3), 0.5, np.float32)),
                                             light=Light(radiance=np.ones(3)), config={}, figures={}))
    gt = root / "capture" / "ground_truth"
    gt.mkdir(parents=True)
    write_body_model(gt, body)
    (root / "config.toml").write_text(QUICK_ANIMATE_CONFIG)
    return root


@pytest.mark.slow
def test_animate_a_shipped_clip_then_refuse_a_bad_one_losing_nothing(scene, tmp_path, capsys):
    out = tmp_path / "run"
    args = ["animate", str(scene / "asset"), "--capture", str(scene / "capture"), "--config",
            str(scene / "config.toml"), "--out", str(out), "--quiet", "--json"]
    assert main(args[:2] + ["--motion", "cmu:02_03"] + args[2:]) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["motion"] == "cmu:02_03" and meta["fps"] == 30.0 and meta["frames"] == 13
    body = np.load(out / "body.npz")["vertices"]
    rest = np.load(scene / "capture" / "ground_truth" / "body_model.npz")["vertices"]
    np.testing.assert_allclose(body[0], rest, atol=1e-5)  # frame 0: the capture pose
    garment = np.load(out / "garment.npz")["vertices"]
    assert garment.shape[0] == 13 and np.all(np.isfinite(garment))
    assert max(meta["figures"]["penetration_fraction"]) < 0.01
    def written() -> dict[str, bytes]:  # the run's files (not the folder lock, which records the last command)
        return {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != LOCK_NAME}

    before = written()
    capsys.readouterr()

    bad = tmp_path / "02_03.amc"
    text = (Path(__file__).parents[1] / "pgc" / "data" / "motions" / "cmu" / "02_03.amc").read_text()
    bad.write_text(re.sub(r"rtibia [^\r\n]+", "rtibia nan", text, count=1))
    (tmp_path / "02.asf").write_text((Path(__file__).parents[1] / "pgc" / "data" / "motions" / "cmu" / "02.asf")
                                     .read_text())
    assert main(args[:2] + ["--motion", str(bad)] + args[2:]) != 0
    err = capsys.readouterr().err
    assert "02_03.amc" in err and "NaN or infinite angles" in err and "Traceback" not in err
    assert written() == before
