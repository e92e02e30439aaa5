"""Relit evaluation: `pgc eval` renders the ground truth under the light `pgc render` used (the capture light or
an environment map file turned per frame), records that light in metrics.json, and refuses with one
`pgc eval: error:` line (exit 2) every comparison it cannot make.

The refusals run on a small hand-made run (written by the real writers); the end-to-end check relights a run of
the tiny demo and is marked slow.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.cli import main
from pgc.io.asset import write_asset
from pgc.io.light_record import (capture_record, envmap_record, identity, public, render_light, rotation_at,
                                 same_light, sha256_file)
from pgc.pipeline.evaluate import RENDER_INPUTS, ground_truth_key, render_inputs
from pgc.pipeline.stage_io import save_npz
from pgc.types import GarmentAsset, GaussianSet, Light, Material

TINY_CONFIG = Path(__file__).resolve().parents[1] / "pgc" / "presets" / "demo_tiny.toml"
H, W = 32, 32


# ---- the light record --------------------------------------------------------------------------------------

def test_an_environment_map_record_names_the_file_its_hash_and_the_angle_of_each_frame(tmp_path):
    env = tmp_path / "sky.exr"
    env.write_bytes(b"not decoded here")
    turning = envmap_record(env, [0, 5, 10], [0.0, 120.0, 240.0])
    assert turning["file"] == "sky.exr" and turning["sha256"] == sha256_file(env) and len(turning["sha256"]) == 64
    assert [rotation_at(turning, t) for t in (0, 5, 10)] == [0.0, 120.0, 240.0]
    with pytest.raises(KeyError):
        rotation_at(turning, 3)
    fixed = envmap_record(env, [0, 5, 10], 30.0)
    assert rotation_at(fixed, 7) == 30.0
    assert public(turning, [0, 5, 10]) == {"kind": "envmap", "file": "sky.exr", "sha256": sha256_file(env),
                                           "frames": [0, 5, 10], "rotation_deg": [0.0, 120.0, 240.0]}
    assert "path" not in public(fixed, [0])  # metrics.json: the name and the hash
    assert same_light(turning, dict(turning), [0, 5, 10])
    assert not same_light(turning, fixed, [0, 5, 10])
    assert not same_light(turning, capture_record(), [0])
    assert same_light(turning, envmap_record(env, [0, 5], [0.0, 120.0]), [0, 5])  # the evaluated frames decide
    assert not same_light(turning, envmap_record(env, [0, 5], [0.0, 120.0]), [0, 5, 10])  # no angle for frame 10


def test_the_ground_truth_key_holds_the_light(tmp_path):
    from pgc.config import load

    run, capture = tmp_path / "run", tmp_path / "capture"
    (capture / "ground_truth").mkdir(parents=True)
    run.mkdir()
    for path in (run / "garment.npz", run / "body.npz", capture / "ground_truth" / "scene.json"):
        path.write_text(path.name)
    sky, studio = tmp_path / "sky.exr", tmp_path / "studio.exr"
    sky.write_bytes(b"sky")
    studio.write_bytes(b"studio")
    cfg = load(require_available=False)
    frames = [0, 5]

    def key(record):
        return ground_truth_key(run, capture, ["cam000"], cfg, identity(record, frames))

    captured = key(capture_record())
    assert captured == ground_truth_key(run, capture, ["cam000"], cfg)  # the default is the capture light
    keys = {captured, key(envmap_record(sky, frames, 0.0)), key(envmap_record(sky, frames, 90.0)),
            key(envmap_record(sky, frames, [0.0, 180.0])), key(envmap_record(studio, frames, 0.0))}
    assert len(keys) == 5  # capture light, two fixed rotations, a turning one, another file
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    shutil.copy(sky, moved / "sky.exr")  # the same bytes elsewhere: the same light
    assert key(envmap_record(moved / "sky.exr", frames, 90.0)) == key(envmap_record(sky, frames, 90.0))


def test_only_scene_renderers_that_declare_environment_maps_render_them():
    from pgc.roles.scene_renderer import SceneRenderer
    from pgc_mitsuba.synth_scene import MitsubaSceneRenderer

    assert SceneRenderer.light_kinds == ("constant",)
    assert set(MitsubaSceneRenderer.light_kinds) == {"constant", "envmap"}


# ---- refusals on a hand-made run ---------------------------------------------------------------------------

def _asset() -> GarmentAsset:
    rng = np.random.default_rng(0)
    garment = seamed_cube()
    n = 12
    gaussians = GaussianSet(parent=rng.integers(0, len(garment.faces), n), means=rng.normal(size=(n, 3)),
                            quats=rng.normal(size=(n, 4)), log_scales=rng.normal(-3, 1, (n, 3)),
                            opacity_logits=rng.normal(size=n), sh=rng.normal(size=(n, 1, 3)))
    return GarmentAsset(garment=garment, body=seamed_cube(), gaussians=gaussians,
                        material=Material("lambertian", {}, rng.random((8, 8, 3)).astype(np.float32)),
                        light=Light(radiance=np.array([1.0, 0.9, 0.8])), config={}, figures={})


def _run(root: Path, light: dict | None) -> Path:
    """A rendered run of frames 0 and 3 from one camera whose render.json records ``light``."""
    write_asset(root / "asset", _asset())
    body = seamed_cube()
    frames = np.stack([body.vertices + [0, 0.01 * t, 0] for t in range(4)])
    run = root / "run"
    (run / "render").mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"asset": str(root / "asset"), "capture": None, "motion": "m",
                                              "fps": 30.0, "frames": 4, "simulator": "xpbd"}))
    save_npz(run / "garment.npz", vertices=frames, faces=body.faces)
    save_npz(run / "body.npz", vertices=frames, faces=body.faces)
    meta = {"frames": [0, 3], "cameras": ["cam00"], "inputs": render_inputs(run)}
    if light is not None:
        meta["light"] = light
    (run / "render" / "render.json").write_text(json.dumps(meta))
    rng = np.random.default_rng(1)
    for t in (0, 3):
        color = rng.random((1, H, W, 3)).astype(np.float32)
        ones = np.ones((1, H, W), np.float32)
        save_npz(run / "render" / f"frame_{t:04d}.npz", hybrid=color, near=color, pbr=color, alpha=ones,
                 pbr_alpha=ones)
    (run / "render" / RENDER_INPUTS).write_text(json.dumps(render_inputs(run)))
    return run


def _image_folder(folder: Path, light: dict | None) -> Path:
    from pgc.io.images import write_image

    folder.mkdir(parents=True)
    rng = np.random.default_rng(2)
    for t in (0, 3):
        write_image(folder / f"frame_{t:04d}_cam00.png", rng.random((H, W, 3)).astype(np.float32))
    if light is not None:
        (folder / "light.json").write_text(json.dumps(light))
    return folder


def _synthetic_capture(folder: Path) -> Path:
    """A folder eval takes for a synthetic capture (its refusals come before anything in it is read)."""
    (folder / "ground_truth").mkdir(parents=True)
    return folder


def _sky(root: Path, data: bytes = b"an environment map") -> Path:
    path = root / "sky.exr"
    path.write_bytes(data)
    return path


def _turning(sky: Path) -> dict:
    return {"radiance": [1.0, 0.9, 0.8], "envmap": True, "rotating": True,
            **envmap_record(sky, [0, 3], [0.0, 180.0])}


def _refused(argv: list, capsys, *words: str) -> str:
    capsys.readouterr()
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pgc eval: error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def test_renders_whose_light_file_is_gone_or_changed_are_refused(tmp_path, capsys):
    sky = _sky(tmp_path)
    run = _run(tmp_path, _turning(sky))
    gt = _synthetic_capture(tmp_path / "capture")
    sky.write_bytes(b"another environment map")
    _refused(["eval", run, "--gt", gt, "--quiet"], capsys, "render.json", "sky.exr", "changed", "pgc render")
    sky.unlink()
    _refused(["eval", run, "--gt", gt, "--quiet"], capsys, "render.json", "sky.exr", "no longer exists",
             "pgc render")
    assert not (run / "metrics.json").exists()


@pytest.mark.parametrize("light, words", [
    ({"radiance": [1, 1, 1], "envmap": True, "rotating": False}, ["'light'", "not which file", "pgc render"]),
    ({"kind": "envmap", "file": None}, ["'file' is not recorded", "pgc render"]),
    ({"kind": "constant", "radiance": [2.0, 2.0, 2.0]}, ["'constant' light", "pgc render"]),
    ({"kind": "area"}, ["'area' light", "pgc render"]),
], ids=["before-the-record", "envmap-without-file", "other-constant", "unknown-kind"])
def test_renders_under_a_light_that_cannot_be_reproduced_are_refused(tmp_path, capsys, light, words):
    run = _run(tmp_path, light)
    _refused(["eval", run, "--gt", _synthetic_capture(tmp_path / "capture"), "--quiet"], capsys, *words)


def test_a_scene_renderer_without_environment_maps_is_refused(tmp_path, capsys, monkeypatch):
    from pgc_mitsuba.synth_scene import MitsubaSceneRenderer

    monkeypatch.setattr(MitsubaSceneRenderer, "light_kinds", ("constant",))
    run = _run(tmp_path, _turning(_sky(tmp_path)))
    _refused(["eval", run, "--gt", _synthetic_capture(tmp_path / "capture"), "--quiet"], capsys,
             "scene renderer 'mitsuba'", "cannot reproduce", "sky.exr", "[scene_renderer]")


def test_a_folder_of_ground_truth_images_must_be_lit_as_the_renders(tmp_path, capsys):
    sky = _sky(tmp_path)
    relit = _run(tmp_path / "a", _turning(sky))
    unrelit = _run(tmp_path / "b", None)
    silent = _image_folder(tmp_path / "silent", None)
    _refused(["eval", relit, "--gt", silent, "--quiet"], capsys, "silent", "no light.json", "sky.exr")
    captured = _image_folder(tmp_path / "captured", capture_record())
    _refused(["eval", relit, "--gt", captured, "--quiet"], capsys, "captured", "the capture light", "sky.exr")
    other_turn = _image_folder(tmp_path / "other_turn", envmap_record(sky, [0, 3], [0.0, 90.0]))
    _refused(["eval", relit, "--gt", other_turn, "--quiet"], capsys, "other_turn", "rotating 0-90 deg")
    _refused(["eval", unrelit, "--gt", other_turn, "--quiet"], capsys, "other_turn", "the capture light")
    broken = _image_folder(tmp_path / "broken", {"kind": "envmap", "file": "sky.exr"})
    _refused(["eval", relit, "--gt", broken, "--quiet"], capsys, "light.json", "'sha256' is not recorded")
    for run in (relit, unrelit):
        assert not (run / "metrics.json").exists()
    # the same light, stated by the folder: compared, and metrics.json says under which light
    same = _image_folder(tmp_path / "same", {k: v for k, v in _turning(sky).items() if k != "path"})
    capsys.readouterr()
    assert main(["eval", str(relit), "--gt", str(same), "--quiet", "--config", str(TINY_CONFIG)]) == 0
    light = json.loads((relit / "metrics.json").read_text())["light"]
    assert light == {"kind": "envmap", "file": "sky.exr", "sha256": sha256_file(sky), "frames": [0, 3],
                     "rotation_deg": [0.0, 180.0]}
    # a folder without light.json still serves renders of the capture light, recorded as such
    assert main(["eval", str(unrelit), "--gt", str(silent), "--quiet", "--config", str(TINY_CONFIG)]) == 0
    assert json.loads((unrelit / "metrics.json").read_text())["light"] == {"kind": "capture"}


def test_render_light_of_an_unrelit_run_is_the_capture_light(tmp_path):
    meta_path = tmp_path / "render.json"
    for light in (None, {"radiance": [1, 1, 1], "envmap": False, "rotating": False},
                  {"radiance": [1, 1, 1], "envmap": False, "rotating": True, "kind": "capture"}):
        assert render_light({"light": light} if light else {}, meta_path, [0], "fix") == capture_record()


# ---- end to end on the tiny demo ---------------------------------------------------------------------------

def _scores(run: Path, light: dict | None) -> dict[str, dict[str, float]]:
    """PSNR and LPIPS of the run's frames against the synthetic ground truth under ``light`` (None: the capture
    light), computed as `pgc eval` does."""
    from pgc import config
    from pgc.events import Reporter
    from pgc.pipeline.evaluate import (VARIANTS, eval_region, layer_alpha, read_frame, rendered_frames,
                                       synthetic_ground_truth)

    cfg = config.load(TINY_CONFIG)
    meta, frames = rendered_frames(run)
    capture = Path(json.loads((run / "run.json").read_text())["capture"])
    truth = synthetic_ground_truth(run, capture, frames, meta["cameras"], cfg,
                                   Reporter.silent(), light)
    metrics = {n: m for n, m in cfg.roles["metric"].create_all().items() if n in ("psnr", "lpips")}
    out: dict[str, dict[str, list[float]]] = {k: {n: [] for n in metrics} for k in VARIANTS}
    for t, gt in zip(frames, truth):
        pred = read_frame(run / "render" / f"frame_{t:04d}.npz", "")
        target = gt["color"] * gt["garment_mask"][..., None]
        for key, layer in VARIANTS.items():
            alpha = pred[layer_alpha(layer, pred)]
            for n, m in metrics.items():
                out[key][n].append(np.mean([m(pred[layer][c], target[c], eval_region(gt["garment_mask"][c], alpha[c]))
                                            for c in range(len(target))]))
    return {k: {n: float(np.mean(v)) for n, v in d.items()} for k, d in out.items()}


@pytest.mark.slow
def test_relit_renders_are_evaluated_against_relit_truth(tiny_demo, tmp_path, capsys):
    demo = tiny_demo
    run = tmp_path / "relit"
    shutil.copytree(demo / "runs" / "spooky", run)
    sky = tmp_path / "sky.exr"
    shutil.copy(demo / "capture" / "ground_truth" / "envmaps" / "sky.exr", sky)
    assert main(["render", str(run), "--light", str(sky), "--rotate-light", "--quiet",
                 "--config", str(TINY_CONFIG)]) == 0
    rendered = json.loads((run / "render" / "render.json").read_text())
    assert rendered["light"]["kind"] == "envmap" and rendered["light"]["sha256"] == sha256_file(sky)
    assert main(["eval", str(run), "--gt", str(demo / "capture"), "--quiet", "--config", str(TINY_CONFIG)]) == 0
    metrics = json.loads((run / "metrics.json").read_text())
    frames = rendered["frames"]
    assert metrics["light"] == public(rendered["light"], frames)
    assert metrics["light"]["rotation_deg"] == [360.0 * i / len(frames) for i in range(len(frames))]
    # relit and capture-light truth live under different keys of RUN/gt (the capture one came with the copy)
    relit_truth = _scores(run, render_light(rendered, run / "render" / "render.json", frames, ""))
    captured_truth = _scores(run, None)
    assert len([p for p in (run / "gt").iterdir() if p.is_dir()]) == 2
    for key in ("hybrid", "pbr_only"):
        assert metrics[key]["psnr"] == pytest.approx(relit_truth[key]["psnr"], abs=1e-6)
        # the relit frames are far closer to the truth under their own light (tiny demo: about +5.6 dB)
        assert relit_truth[key]["psnr"] > captured_truth[key]["psnr"] + 3.0, (relit_truth, captured_truth)
        assert relit_truth[key]["lpips"] < captured_truth[key]["lpips"]
    capsys.readouterr()
    assert main(["info", str(run)]) == 0
    assert "metrics against ground truth lit by environment map sky.exr" in capsys.readouterr().out
    sky.write_bytes(sky.read_bytes() + b"\0")  # the light file changed after rendering: refused
    _refused(["eval", run, "--gt", demo / "capture", "--quiet"], capsys, "sky.exr", "changed")
