"""End to end: `pgc demo --preset tiny` (synthetic capture -> asset -> three motions -> metrics, report).

The demo checked is the session's ``tiny_demo`` (tests/conftest.py: one demo for the whole suite, which
tests/test_eval_relit.py, tests/test_report.py and others read too); the resume and the kernel rule are checked on a
copy of it whose renders are removed, so that the rerun renders every motion and light again in this process.
"""

import json
import shutil

import numpy as np
import pytest

from pgc.cli import main


@pytest.mark.slow
def test_tiny_demo_runs_end_to_end_and_reports_every_variant(tiny_demo, tmp_path, monkeypatch):
    from pgc.pipeline import render as render_stage

    out = tiny_demo  # read only: the resume below runs on a copy
    metrics = json.loads((out / "metrics.json").read_text())
    for variant in ("hybrid", "3dgs_only", "pbr_only"):
        for name in ("psnr", "ssim", "fsim", "lpips"):
            assert np.isfinite(metrics[variant][name]), (variant, name)
    assert set(metrics["motions"]) == {"goalpost", "spooky", "arms-up", "cmu:02_01"}  # the paper's and a CMU clip
    assert (out / "report.html").is_file() and any((out / "report").glob("*.png"))
    # every variant under the capture light and two novel lights, each measured against truth under it
    assert list(metrics["lights"]) == ["capture", "sky-rot90", "low-key"]
    assert metrics["lights"]["capture"]["hybrid"] == metrics["motions"]["spooky"]["hybrid"]  # on the relit motion
    for name, light in metrics["lights"].items():
        assert light["light"]["kind"] == ("capture" if name == "capture" else "envmap")
        assert set(light["motions"]) == {"spooky"}
        for variant in ("hybrid", "3dgs_only", "pbr_only"):
            assert np.isfinite(light[variant]["psnr"]) and np.isfinite(light[variant]["lpips"])
    relit = out / "runs" / "spooky" / "relit" / "low-key"
    assert json.loads((relit / "metrics.json").read_text())["light"] == metrics["lights"]["low-key"]["light"]
    assert metrics["lights"]["low-key"]["light"]["sha256"] != metrics["lights"]["sky-rot90"]["light"]["sha256"]
    assert metrics["lights"]["sky-rot90"]["light"]["rotation_deg"] == 90.0
    assert not (out / "runs" / "goalpost" / "relit").exists()
    page = (out / "report.html").read_text()
    assert "Under novel lights" in page and "low-key_spooky_" in page and "_gt.png" in page
    # the hybrid takes the far field's outline (silhouette = "far"); with the mesh as far field, the mesh's
    render = out / "runs" / "goalpost" / "render"
    meta = json.loads((render / "render.json").read_text())
    frame = np.load(render / f"frame_{meta['frames'][-1]:04d}.npz")
    if meta["far_source"] == "mesh":
        np.testing.assert_array_equal(frame["hybrid_alpha"], frame["pbr_alpha"])
    assert np.all(frame["hybrid"][frame["hybrid_alpha"] == 0] == 0)  # over black outside the outline
    # the asset is complete and a rerun resumes from the cache: with the renders gone, the asset and the animations
    # are not recomputed, and the kernel rule runs once for the four motions and the three lights (once per process)
    assert (out / "asset" / "manifest.json").is_file()
    out = tmp_path / "demo"
    shutil.copytree(tiny_demo, out)
    renders = [p for p in out.glob("runs/**/render") if (p / "stage.json").is_file()]
    assert len(renders) == 6  # four motions under the capture light, spooky under two novel lights
    for folder in renders:
        shutil.rmtree(folder)
    stamp = {p: p.stat().st_mtime for p in out.rglob("stage.json")}
    assert {p.parents[2].name for p in stamp if p.parent.name == "animate"} == set(metrics["motions"])
    assert any(p.is_relative_to(out / "asset" / "stages") for p in stamp)
    calls = []
    rule = render_stage.choose_kernel
    monkeypatch.setattr(render_stage, "choose_kernel", lambda *a: calls.append(1) or rule(*a))
    assert main(["demo", "--preset", "tiny", "--out", str(out), "--quiet"]) == 0
    assert len(calls) == 1  # one asset, four motions, three lights: the kernel rule runs once per process
    assert {p: p.stat().st_mtime for p in stamp} == stamp
    assert all((folder / "stage.json").is_file() for folder in renders)
    assert json.loads((out / "metrics.json").read_text())["lights"].keys() == metrics["lights"].keys()


def test_scene_presets_without_their_own_settings_take_the_default_demo_settings():
    """`pgc demo --preset cotton|knit` runs another synth scene under demo_default.toml; tiny has its own."""
    from pgc.pipeline.demo import demo_config
    from pgc.synth.generate import PRESETS

    default = demo_config("default").to_dict()
    for name in ("cotton", "knit"):
        assert name in PRESETS
        assert demo_config(name).to_dict() == default
    assert demo_config("tiny").to_dict() != default


def test_the_demo_scene_is_a_fibre_truth_with_near_field_detail_and_the_cotton_scene_keeps_the_earlier_default():
    from pgc.synth.fabrics import HAIR_FIBRES, get_fabric
    from pgc.synth.generate import get_preset

    scene = get_preset("default")
    assert (scene.framing, scene.detail, scene.fit, scene.views) == ("garment", "seams", "resting", 128)
    assert scene.fabric == "cotton" and get_fabric(scene.fabric).appearance == HAIR_FIBRES
    cotton = get_preset("cotton")
    assert (cotton.framing, cotton.detail, cotton.fit, cotton.resolution, cotton.views) == ("body", "none", "loose",
                                                                                            256, 128)


