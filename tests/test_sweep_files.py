"""The shipped sweep files (examples/sweeps/) parse and expand to the grids the paper's tables promise (issue 34:
3 BRDFs x >= 4 fibre fabrics x 2 seeds on held-out views and 2 novel lights; 3 variants on >= 3 scenes x 2 seeds x
>= 3 motions with a CMU clip, both evaluation modes), counted from the planned tasks without running them; and the
sweep keys ``modes`` and ``holdout_every``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import fast_sweep_config
from pgc.errors import PGCConfigError

SWEEPS = Path(__file__).parents[1] / "examples" / "sweeps"
NOVEL_LIGHTS = {"sky-rot90", "low-key"}


def _plan(name: str, tmp_path: Path):
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan

    sweep = load_sweep(SWEEPS / f"{name}.toml")
    tasks, units, done = plan(sweep, tmp_path / "out")
    assert not done and not (tmp_path / "out").exists()  # planning writes nothing
    return sweep, tasks, units


def _is_fibre_truth(fabric: str) -> bool:
    from pgc.synth.fabrics import FABRICS

    return FABRICS[fabric].hair is not None


@pytest.mark.parametrize("name, base", [("paper-pbr", "default"), ("paper-pbr-tiny", "tiny")])
def test_pbr_table_sweeps_expand_to_brdfs_x_fibre_fabrics_x_seeds(tmp_path, name, base):
    sweep, tasks, units = _plan(name, tmp_path)
    brdfs = {c.name: c.cfg.roles["brdf"].name for c in sweep.configurations}
    assert brdfs == {"lambertian": "lambertian", "disney": "disney", "pgc-sheen": "pgc-sheen"}
    assert {c.cfg.stage("material").max_iterations for c in sweep.configurations} == (
        {20} if base == "tiny" else {3000})
    fabrics = {s.synth["fabric"] for s in sweep.scenes}
    seeds = {s.synth["seed"] for s in sweep.scenes}
    assert len({f for f in fabrics if _is_fibre_truth(f)}) >= 4 and seeds == {0, 1}
    assert {s.synth["preset"] for s in sweep.scenes} == {base}
    assert len(sweep.scenes) == len(fabrics) * len(seeds)
    assert set(sweep.lights) == {"capture"} | NOVEL_LIGHTS and sweep.modes == ["appearance"]
    assert sweep.holdout_every >= 2
    assert len(units) == 3 * len(fabrics) * len(seeds) * len(sweep.motions)
    kinds = [t.key.split("-")[0] for t in tasks]
    assert kinds.count("capture") == kinds.count("split") == len(sweep.scenes)
    assert kinds.count("asset") == kinds.count("run") == len(units)
    for u in units:  # reconstructed from the training views, rendered and evaluated from the held-out ones
        asset = next(t for t in tasks if t.key == u.asset_task)
        assert asset.args[0].endswith(f"-train{sweep.holdout_every}")
        assert u.capture.endswith(f"-heldout{sweep.holdout_every}")
    t = sweep.table
    assert t.where == {"variant": ["pbr_only"]} and t.metrics == ["psnr", "psnr-exposure", "lpips"]
    assert t.rows == ["configuration", "light"] and t.columns == ["fabric"]


@pytest.mark.parametrize("name, base", [("paper-ablation", "default"), ("paper-ablation-tiny", "tiny")])
def test_ablation_sweeps_expand_to_scenes_x_seeds_x_motions_in_both_modes(tmp_path, name, base):
    sweep, tasks, units = _plan(name, tmp_path)
    scenes = {(s.synth["garment"], s.synth["fabric"]) for s in sweep.scenes}
    seeds = {s.synth["seed"] for s in sweep.scenes}
    assert len(scenes) >= 3 and seeds == {0, 1} and len(sweep.scenes) == len(scenes) * len(seeds)
    assert {g for g, _ in scenes} == {"tshirt", "dress"}
    assert {"fleece", "knit"} <= {f for _, f in scenes} and all(_is_fibre_truth(f) for _, f in scenes)
    assert {s.synth["preset"] for s in sweep.scenes} == {base}
    assert len(sweep.motions) >= 3 and any(m.startswith("cmu:") for m in sweep.motions)
    assert set(sweep.lights) == {"capture"} | NOVEL_LIGHTS
    assert sweep.modes == ["appearance", "independent"] and sweep.holdout_every == 0
    (conf,) = sweep.configurations
    assert {"psnr", "psnr-exposure", "ssim", "fsim", "lpips"} <= {i.name for i in conf.cfg.roles["metric"].implementations}
    assert conf.cfg.roles["body_model"].name == "anny"
    assert len(units) == len(sweep.scenes) * len(sweep.motions)
    kinds = [t.key.split("-")[0] for t in tasks]
    assert kinds.count("run") == kinds.count("eval") == len(units)
    # breadth first: a run's priority falls with its motion's index, every mode task's below every run's
    runs = {t.key: t.priority for t in tasks if t.key.startswith("run-")}
    assert {runs[u.run_task] for u in units if u.motion == sweep.motions[0]} == {0}
    assert {runs[u.run_task] for u in units if u.motion == sweep.motions[-1]} == {1 - len(sweep.motions)}
    assert max(t.priority for t in tasks if t.key.startswith("eval-")) < min(runs.values())
    assert all(set(u.mode_tasks) == {"appearance", "independent"} and u.mode_tasks["appearance"] == u.run_task
               for u in units)
    t = sweep.table
    assert t.rows == ["variant"] and t.columns == ["mode", "light"]
    assert set(t.metrics) == {"psnr", "psnr-exposure", "ssim", "fsim", "lpips"}


GOOD = """
[sweep]
steps = ["reconstruct", "animate", "render", "eval"]
motions = ["goalpost"]
lights = ["capture"]
[scenes.a]
preset = "tiny"
[configurations.base]
"""


@pytest.mark.parametrize("old, new, message", [
    ('lights = ["capture"]', 'modes = ["matched"]', "[sweep].modes: unknown mode 'matched'"),
    ('lights = ["capture"]', 'modes = []', "[sweep].modes: give a non-empty list"),
    ('lights = ["capture"]', 'modes = ["independent", "independent"]', "[sweep].modes: a mode is named twice"),
    ('"render", "eval"]', '"render"]\nmodes = ["independent"]', "[sweep].modes: evaluation modes need the step"),
    ('lights = ["capture"]', 'holdout_every = 1', "[sweep].holdout_every: 1: give an integer >= 2"),
    ('preset = "tiny"', 'preset = "tiny"\nviews = 1', "[scenes.a].views: 1: give the number of capture cameras"),
    ('lights = ["capture"]', 'holdout_every = true', "[sweep].holdout_every: True: give"),
    ('"animate", "render", "eval"]', '"animate"]\nholdout_every = 3', "[sweep].holdout_every: held-out views"),
])
def test_bad_modes_holdout_and_views_fail_naming_file_and_key(tmp_path, old, new, message):
    from pgc.sweep.spec import load_sweep

    assert old in GOOD
    path = tmp_path / "sw.toml"
    path.write_text(GOOD.replace(old, new))
    with pytest.raises(PGCConfigError) as exc:
        load_sweep(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


def test_modes_become_a_table_column_and_a_task_per_run(tmp_path):
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan

    path = tmp_path / "sw.toml"
    path.write_text(GOOD.replace('lights = ["capture"]', 'lights = ["capture", "low-key"]\n'
                                                          'modes = ["appearance", "independent"]'))
    sweep = load_sweep(path)
    assert sweep.table.columns == ["light", "mode"]
    tasks, units, _ = plan(sweep, tmp_path / "out")
    (unit,) = units
    ev = next(t for t in tasks if t.key == unit.mode_tasks["independent"])
    assert ev.deps == (unit.run_task,) and ev.key == "eval-independent-" + unit.run_task.split("-", 1)[1]
    # without modes, nothing changes: the same run key, no eval task
    path.write_text(GOOD.replace('lights = ["capture"]', 'lights = ["capture", "low-key"]'))
    _, plain_units, _ = plan(load_sweep(path), tmp_path / "out")
    assert plain_units[0].run_task == unit.run_task and plain_units[0].mode_tasks == {"appearance": unit.run_task}


def test_records_carry_the_mode_and_a_failed_mode_task_fails_only_its_mode(tmp_path):
    from pgc.sweep.runner import records_of
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan

    path = tmp_path / "sw.toml"
    path.write_text(GOOD.replace('lights = ["capture"]', 'modes = ["appearance", "independent"]\n'
                                                          'lights = ["capture", "low-key"]'))
    sweep = load_sweep(path)
    _, (u,), _ = plan(sweep, tmp_path / "out")
    variant = {"hybrid": {"psnr": 20.0}, "3dgs_only": {"psnr": 15.0}, "pbr_only": {"psnr": 19.0}}
    results = {u.asset_task: {"asset": "A", "brdf": "pgc-sheen", "figures": {}, "seconds": 1.0},
               u.run_task: {"run": "R", "seconds": {"animate": 2.0},
                            "metrics": {"capture": variant, "low-key": variant}},
               u.mode_tasks["independent"]: {"run": "R", "seconds": {"eval_independent": 3.0},
                                             "metrics": {"capture": variant, "low-key": variant}}}
    records = records_of(sweep, [u], results, {})
    assert len(records) == 2 * 2 * 3
    assert {(r["mode"], r["light"]) for r in records} == {(m, x) for m in ("appearance", "independent")
                                                           for x in ("capture", "low-key")}
    ind = [r for r in records if r["mode"] == "independent"]
    assert all(r["seconds"] == {"reconstruct": 1.0, "animate": 2.0, "eval_independent": 3.0} for r in ind)
    failed = records_of(sweep, [u], results, {u.mode_tasks["independent"]: "RuntimeError: x"})
    assert len(failed) == 2 * 3 + 1 and failed[-1]["mode"] == "independent" and failed[-1]["failed"]


def test_split_holds_out_every_kth_view_with_the_ground_truth_in_both(tmp_path):
    from pgc.io.capture import read_capture, write_capture
    from pgc.sweep.work import make_split
    from pgc.testing.capture_scenes import textured_box_capture

    capture = tmp_path / "cap"
    write_capture(capture, textured_box_capture(views=7, size=16))
    (capture / "ground_truth").mkdir()
    (capture / "ground_truth" / "scene.json").write_text("{}")
    full = read_capture(capture)
    result = make_split(str(capture), str(tmp_path / "train"), str(tmp_path / "held"), 3, "split-x-3", str(tmp_path))
    train, held = read_capture(tmp_path / "train"), read_capture(tmp_path / "held")
    names = [v.camera.name for v in full.views]
    assert [v.camera.name for v in held.views] == [names[2], names[5]]
    assert [v.camera.name for v in train.views] == [n for i, n in enumerate(names) if i not in (2, 5)]
    by_name = {v.camera.name: v for v in full.views}
    for view in train.views + held.views:  # the same pixels and cameras
        np.testing.assert_array_equal(view.image, by_name[view.camera.name].image)
        np.testing.assert_array_equal(view.camera.K, by_name[view.camera.name].camera.K)
    for folder in ("train", "held"):
        assert (tmp_path / folder / "ground_truth" / "scene.json").read_text() == "{}"
    held_files = {p.name for p in (tmp_path / "held").rglob("*") if p.is_file()}
    assert not any(n.startswith(names[0]) for n in held_files)  # a training view's files stay out
    assert result["views_train"] == 5 and result["views_heldout"] == 2
    assert json.loads((tmp_path / "results" / "split-x-3.json").read_text()) == result
    with pytest.raises(Exception, match="too few to hold out every 4th view"):
        make_split(str(capture), str(tmp_path / "t2"), str(tmp_path / "h2"), 4, "split-y-4", str(tmp_path))


HELD_OUT_BOTH_MODES = """
[sweep]
name = "m"
base = "tiny"
config = "{fast}"
motions = ["goalpost"]
lights = ["capture", "low-key"]
modes = ["appearance", "independent"]
holdout_every = 3
[scenes.s]
preset = "tiny"
[configurations.lambertian]
brdf = {{ use = "lambertian" }}
stages.eval.truth_options = {{ substeps = 2, iterations = 2, settle_frames = 2 }}
[configurations.pgc-sheen]
brdf = {{ use = "pgc-sheen" }}
stages.eval.truth_options = {{ substeps = 2, iterations = 2, settle_frames = 2 }}
"""


@pytest.mark.slow
def test_tiny_sweep_on_held_out_views_in_both_modes(tmp_path):
    from pgc.io.capture import read_capture
    from pgc.sweep.runner import run_sweep

    path = tmp_path / "m.toml"
    path.write_text(HELD_OUT_BOTH_MODES.format(fast=fast_sweep_config(tmp_path)))
    out = tmp_path / "out"
    result = run_sweep(path, out)
    assert result["failed"] == {} and result["computed"] == 8  # capture, split, 2 assets, 2 runs, 2 mode evals
    records = result["records"]
    assert len(records) == 2 * 2 * 2 * 3  # configurations x modes x lights x variants
    (held,) = {r["capture"] for r in records}
    assert held.endswith("-heldout3")
    held_names = [c.name for c in read_capture(held).cameras]
    assert len(held_names) == 2  # views 2 and 5 of 6
    for r in records:
        assert all(math.isfinite(v) for v in r["metrics"].values())
        folder = Path(r["run"]) / ("relit/low-key" if r["light"] == "low-key" else "")
        metrics = json.loads((folder / "metrics.json").read_text())
        assert metrics["cameras"] == held_names  # rendered and evaluated from the held-out views only
        assert set(metrics["modes"]) == {"appearance", "independent"}
        assert metrics["modes"][r["mode"]][r["variant"]]["psnr"] == r["metrics"]["psnr"]
        manifest = json.loads((Path(r["asset"]) / "manifest.json").read_text())
        assert Path(manifest["config"]["source"]["capture"]).name.endswith("-train3")
    by = {(r["configuration"], r["mode"], r["light"], r["variant"]): r["metrics"]["psnr"] for r in records}
    # the independent truth differs from the matched one, and is simulated once per run (the relit run reuses it)
    matched = by[("lambertian", "appearance", "capture", "hybrid")]
    assert by[("lambertian", "independent", "capture", "hybrid")] != matched
    for run in {r["run"] for r in records}:
        sims = {p.name: p.stat().st_ino for p in (Path(run) / "gt" / "truth_sim").iterdir()}
        relit = {p.name: p.stat().st_ino for p in (Path(run) / "relit" / "low-key" / "gt" / "truth_sim").iterdir()}
        assert sims and relit == sims
    # the two BRDFs share the scene's simulation and ground-truth renders
    runs = sorted({r["run"] for r in records})
    gts = [sorted(p.name for p in (Path(run) / "gt").iterdir() if p.name != "truth_sim") for run in runs]
    assert gts[0] == gts[1]
    again = run_sweep(path, out)
    assert again["computed"] == 0 and again["records"] == records


def test_collect_tabulates_the_finished_tasks_and_runs_nothing(tmp_path, capsys):
    from pgc.cli import main
    from pgc.sweep.runner import NOT_RUN, run_sweep
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.table import table_grid
    from pgc.sweep.work import plan, result_path

    path = tmp_path / "sw.toml"
    path.write_text(GOOD.replace('motions = ["goalpost"]', 'motions = ["goalpost", "spooky"]'))
    out = tmp_path / "out"
    tasks, units, _ = plan(load_sweep(path), out)
    first = units[0]
    variant = {"hybrid": {"psnr": 20.0}, "3dgs_only": {"psnr": 15.0}, "pbr_only": {"psnr": 19.0}}
    finished = {first.asset_task: {"asset": "A", "brdf": "pgc-sheen", "figures": {}, "seconds": 1.0},
                first.run_task: {"run": "R", "seconds": {"animate": 2.0}, "metrics": {"capture": variant}}}
    for key, value in finished.items():
        result_path(out, key).parent.mkdir(parents=True, exist_ok=True)
        result_path(out, key).write_text(json.dumps(value))
    result = run_sweep(path, out, collect=True)
    assert result["computed"] == 0
    assert set(result["failed"]) == {t.key for t in tasks} - set(finished)
    assert set(result["failed"].values()) == {NOT_RUN}
    done = [r for r in result["records"] if "failed" not in r]
    assert [(r["motion"], r["variant"], r["metrics"]["psnr"]) for r in done] == [
        ("goalpost", "hybrid", 20.0), ("goalpost", "3dgs_only", 15.0), ("goalpost", "pbr_only", 19.0)]
    assert [r["motion"] for r in result["records"] if "failed" in r] == ["spooky"]
    head, grid = table_grid(result["records"], result["table"])
    assert grid == [["base", "18 ± 2.6"]]  # the three variants of the finished unit; the other is no empty row
    assert json.loads((out / "sweep.json").read_text()) == result["records"]
    assert not (out / "captures").exists()  # nothing ran
    assert main(["sweep", str(path), "--out", str(out), "--collect", "--quiet"]) == 0
    assert "not run: 2 tasks" in capsys.readouterr().out
