"""Novel lights in the demo, the sweeps and the report (pgc.pipeline.relight): the low key light, the light files
and relit runs, per-light sweep records and tables, the report's truth under each light, the refusals.

The plumbing runs on hand-made runs (written by the real writers); the tiny demo end to end is in test_demo.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pgc.cli import main
from pgc.errors import PGCConfigError
from pgc.io.light_record import capture_record, envmap_record, public
from pgc.pipeline.evaluate import render_inputs
from pgc.pipeline.relight import EVAL_LIGHTS, light_file, relit_run
from pgc.pipeline.stage_io import save_npz

H = W = 24
FRAMES = [0, 3]


# ---- the lights ---------------------------------------------------------------------------------------------

def _irradiance(env: np.ndarray, normal: np.ndarray) -> float:
    """Cosine-weighted integral of the map's mean channel over the hemisphere around ``normal``."""
    from pgc_torch.pbr.lighting import envmap_directions

    dirs, solid = envmap_directions(env.shape[0], env.shape[1])
    return float(np.sum(env.reshape(-1, 3).mean(1) * solid * np.clip(dirs @ normal, 0, None)))


def test_the_low_key_light_is_one_side_key_over_a_faint_fill():
    from pgc.synth.rig import relight_envmap

    env = relight_envmap(64, "low-key")
    assert env.shape == (64, 128, 3) and np.all(np.isfinite(env)) and env.min() > 0
    key = np.array([np.cos(np.radians(20)) * np.sin(np.radians(70)), np.sin(np.radians(20)),
                    np.cos(np.radians(20)) * np.cos(np.radians(70))])
    from pgc_torch.pbr.lighting import envmap_directions

    dirs, _ = envmap_directions(64, 128)
    brightest = dirs[np.argmax(env.reshape(-1, 3).mean(1))]
    assert np.degrees(np.arccos(np.clip(brightest @ key, -1, 1))) < 3.0  # the key sits where it is said to
    ratio = _irradiance(env, key) / _irradiance(env, -key)
    assert 12 < ratio < 40, ratio  # low key: about 20:1 key to fill
    assert _irradiance(env, key) == pytest.approx(2.0, rel=0.25)  # a facing surface: 2/3 of the capture dome's pi
    with pytest.raises(Exception, match="'sky', 'studio' or 'low-key'"):
        relight_envmap(16, "moon")


def test_light_names_are_checked():
    from pgc.pipeline.relight import check_light_names

    assert check_light_names(["low-key", "capture"], "w") == ["low-key", "capture"]
    for names, words in (([], "at least one light"), (["moon"], "unknown light 'moon'"),
                         (["low-key", "low-key"], "named twice")):
        with pytest.raises(PGCConfigError, match=words):
            check_light_names(names, "w")
    assert set(EVAL_LIGHTS) >= {"capture", "sky-rot90", "low-key"}  # a rotated environment and a low key light


def test_light_files_are_written_once_and_rewritten_when_changed(tmp_path):
    from pgc.io.images import read_envmap, write_exr
    from pgc.synth.rig import relight_envmap

    light = EVAL_LIGHTS["sky-rot90"]
    path = light_file(tmp_path, light)
    assert path.name == "sky.exr" and np.array_equal(read_envmap(path), relight_envmap(64, "sky"))
    stamp = path.stat().st_mtime_ns
    assert light_file(tmp_path, light) == path and path.stat().st_mtime_ns == stamp  # not written again
    write_exr(path, np.ones((8, 16, 3), np.float32))
    light_file(tmp_path, light)
    assert np.array_equal(read_envmap(path), relight_envmap(64, "sky"))


# ---- hand-made runs ---------------------------------------------------------------------------------------

def _run(root: Path, name: str = "run") -> Path:
    """An animated run of 4 frames whose frames 0 and 3 are rendered from one camera, under the capture light."""
    from conftest import seamed_cube

    body = seamed_cube()
    verts = np.stack([body.vertices + [0, 0.01 * t, 0] for t in range(4)])
    run = root / name
    run.mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"asset": str(root / "asset"), "capture": None, "motion": "walk",
                                              "fps": 30.0, "frames": 4, "simulator": "xpbd"}))
    save_npz(run / "garment.npz", vertices=verts, faces=body.faces)
    save_npz(run / "body.npz", vertices=verts, faces=body.faces)
    return run


def _render(run: Path, light: dict, level: float) -> None:
    """Frames of constant ``level`` over a centre square, with the render.json of ``light``."""
    (run / "render").mkdir(parents=True, exist_ok=True)
    alpha = np.zeros((1, H, W), np.float32)
    alpha[:, 6:18, 6:18] = 1
    color = np.full((1, H, W, 3), level, np.float32) * alpha[..., None]
    for t in FRAMES:
        save_npz(run / "render" / f"frame_{t:04d}.npz", hybrid=color, near=color, pbr=color, alpha=alpha,
                 pbr_alpha=alpha, hybrid_alpha=alpha, low_far=color, high_near=0 * color)
    (run / "render" / "render.json").write_text(json.dumps({
        "frames": FRAMES, "cameras": ["cam00"], "inputs": render_inputs(run), "far_source": "mesh",
        "kernel_size": 3, "light": {"radiance": [1, 1, 1], "envmap": light["kind"] == "envmap", "rotating": False,
                                    **light}}))


def _truth(run: Path, light: dict, level: float, key: str) -> None:
    folder = run / "gt" / key
    folder.mkdir(parents=True)
    mask = np.zeros((1, H, W), np.float32)
    mask[:, 5:19, 5:19] = 1
    for t in FRAMES:
        save_npz(folder / f"frame_{t:04d}_spp4.npz", color=np.full((1, H, W, 3), level, np.float32),
                 garment_mask=mask)
    if light["kind"] != "capture":
        (folder / "light.json").write_text(json.dumps(public(light, FRAMES)))


def _metrics(run: Path, light: dict, psnr: float) -> None:
    row = {"psnr": psnr, "lpips": 0.1}
    (run / "metrics.json").write_text(json.dumps({"light": public(light, FRAMES),
                                                  **{v: dict(row) for v in ("hybrid", "3dgs_only", "pbr_only")}}))


def test_a_relit_run_shares_the_simulation_and_follows_it(tmp_path):
    run = _run(tmp_path)
    relit = relit_run(run, "low-key")
    assert relit == run / "relit" / "low-key"
    for name in ("run.json", "garment.npz", "body.npz"):
        assert (relit / name).read_bytes() == (run / name).read_bytes()
    assert render_inputs(relit) == render_inputs(run)  # its frames are checked against the same simulation
    save_npz(run / "garment.npz", vertices=np.zeros((4, 8, 3)), faces=np.zeros((1, 3), np.int64))  # re-animated
    relit_run(run, "low-key")
    assert (relit / "garment.npz").read_bytes() == (run / "garment.npz").read_bytes()
    assert not list(relit.glob(".*.tmp"))


def test_the_report_takes_the_truth_rendered_under_the_frames_light(tmp_path):
    from pgc.pipeline.report import ground_truth_frame

    run = _run(tmp_path)
    env = light_file(tmp_path / "lights", EVAL_LIGHTS["low-key"])
    lit = envmap_record(env, FRAMES, 0.0)
    _truth(run, capture_record(), 0.25, "a")
    _truth(run, lit, 0.75, "b")
    assert ground_truth_frame(run, 3, capture_record()).max() == 0.25
    assert ground_truth_frame(run, 3, lit).max() == 0.75
    assert ground_truth_frame(run, 3, envmap_record(env, FRAMES, 90.0)) is None  # never another light's truth
    assert ground_truth_frame(run, 1, lit) is None  # a frame without truth


def test_the_report_shows_each_light_with_its_truth_error_maps_and_table(tmp_path):
    from pgc.pipeline.report import _Figures, _lights_section, read_run_view, relit_views

    run = _run(tmp_path)
    _render(run, capture_record(), 0.5)
    _truth(run, capture_record(), 0.5, "a")
    _metrics(run, capture_record(), 30.0)
    relit = relit_run(run, "low-key")
    lit = envmap_record(light_file(tmp_path / "lights", EVAL_LIGHTS["low-key"]), FRAMES, 0.0)
    _render(relit, lit, 0.2)
    _truth(relit, lit, 0.3, "b")
    _metrics(relit, lit, 25.5)
    views = [read_run_view(run, "walk")]
    by_light = relit_views(views)
    assert list(by_light) == ["low-key"] and by_light["low-key"][0].folder == relit
    f = _Figures(tmp_path / "out")
    page = _lights_section(by_light, views, f)
    assert "Under novel lights" in page and "low-key" in page
    shown = [p.name for p in f.written]
    for key in ("gt", "3dgs_only", "pbr_only", "hybrid"):
        assert f"low-key_walk_0003_{key}.png" in shown
    for key in ("3dgs_only", "pbr_only", "hybrid"):
        assert f"low-key_walk_0003_{key}_error.png" in shown
    assert all(p.is_file() and p.stat().st_size > 0 for p in f.written)
    truth = np.asarray(Image.open(f.folder / "low-key_walk_0003_gt.png"))
    assert truth.max() > 0  # the relit truth, not an empty picture
    assert "-4.50 dB" in page and "25.5000" in page and "30.0000" in page  # per-light table, change from capture


def test_metrics_of_relit_frames_against_unrelit_truth_are_not_shown(tmp_path):
    from pgc.pipeline.report import _Figures, _lights_section, read_run_view, relit_views

    run = _run(tmp_path)
    _render(run, capture_record(), 0.5)
    _metrics(run, capture_record(), 30.0)
    relit = relit_run(run, "low-key")
    lit = envmap_record(light_file(tmp_path / "lights", EVAL_LIGHTS["low-key"]), FRAMES, 0.0)
    _render(relit, lit, 0.2)
    _truth(relit, capture_record(), 0.5, "a")  # only capture-light truth in the relit run
    _metrics(relit, capture_record(), 99.0)  # as if measured against the capture light
    f = _Figures(tmp_path / "out")
    page = _lights_section(relit_views([read_run_view(run, "walk")]), [read_run_view(run, "walk")], f)
    assert "99.0" not in page and "No ground truth under this run's light yet" in page
    assert not any(p.name.startswith("low-key") and p.name.endswith("_error.png") for p in f.written)


# ---- pgc render --light-rotation ----------------------------------------------------------------------------

@pytest.mark.parametrize("extra, words", [
    (["--light-rotation", "30"], "give it with --light"),
    (["--light", "{env}", "--light-rotation", "30", "--rotate-light"], "not both"),
    (["--light", "{env}", "--light-rotation", "nan"], "finite angle"),
])
def test_render_light_rotation_refusals(tmp_path, capsys, extra, words):
    run = _run(tmp_path)
    env = light_file(tmp_path, EVAL_LIGHTS["low-key"])
    capsys.readouterr()
    assert main(["render", str(run), "--quiet", *[a.format(env=env) for a in extra]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pgc render: error: ") and words in err[0], err


# ---- sweeps -----------------------------------------------------------------------------------------------

SWEEP = """
[sweep]
steps = ["reconstruct", "animate", "render", "eval"]
motions = ["goalpost"]
{lights}
[scenes.a]
preset = "tiny"
[configurations.base]
[table]
rows = ["variant"]
metrics = ["psnr"]
"""


def test_sweeps_evaluate_every_light_by_default_and_tables_never_average_over_lights(tmp_path):
    from pgc.sweep.spec import load_sweep

    path = tmp_path / "sw.toml"
    path.write_text(SWEEP.format(lights=""))
    sweep = load_sweep(path)
    assert sweep.lights == list(EVAL_LIGHTS) and sweep.table.columns == ["light"]
    path.write_text(SWEEP.format(lights='lights = ["capture", "moon"]'))
    with pytest.raises(PGCConfigError, match=r"\[sweep\].lights: unknown light 'moon'"):
        load_sweep(path)
    path.write_text(SWEEP.format(lights='lights = ["capture"]'))
    assert load_sweep(path).table.columns == []


def test_sweep_records_and_tables_are_per_light(tmp_path):
    from pgc.sweep.runner import records_of
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.table import text_table
    from pgc.sweep.work import plan

    path = tmp_path / "sw.toml"
    path.write_text(SWEEP.format(lights='lights = ["capture", "low-key"]'))
    sweep = load_sweep(path)
    tasks, units, _ = plan(sweep, tmp_path / "out")
    run_task = next(t for t in tasks if t.key.startswith("run-"))
    assert "low-key" in run_task.args[7]  # make_run is told the lights
    (unit,) = units
    per = {"capture": {"hybrid": {"psnr": 30.0}, "pbr_only": {"psnr": 28.0}},
           "low-key": {"hybrid": {"psnr": 27.0}, "pbr_only": {"psnr": 26.0}}}
    results = {unit.asset_task: {"brdf": "pgc-sheen", "figures": {}, "asset": "A", "seconds": 1.0},
               unit.run_task: {"run": "R", "seconds": {"render": 1.0, "relit_render": 2.0}, "metrics": per}}
    records = records_of(sweep, units, results, {})
    assert {(r["light"], r["variant"]): r["metrics"]["psnr"] for r in records} == {
        ("capture", "hybrid"): 30.0, ("capture", "pbr_only"): 28.0, ("low-key", "hybrid"): 27.0,
        ("low-key", "pbr_only"): 26.0}
    table = text_table(records, sweep.table).splitlines()
    assert "capture psnr" in table[0] and "low-key psnr" in table[0]
    assert table[1].split()[:3] == ["hybrid", "30", "27"]


def test_the_demo_refuses_unknown_lights_and_relit_motions_before_any_work(tmp_path, capsys):
    from pgc.pipeline.demo import run_demo

    with pytest.raises(PGCConfigError, match="relit motions \\['moonwalk'\\]"):
        run_demo(tmp_path / "d", "tiny", relit_motions=("moonwalk",))
    capsys.readouterr()
    assert main(["demo", "--preset", "tiny", "--out", str(tmp_path / "e"), "--lights", "moon", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown light 'moon'" in err[0], err
    assert not (tmp_path / "d").exists() and not (tmp_path / "e").exists()
