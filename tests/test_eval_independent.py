"""``pgc eval --mode independent``: the truth garment simulated on its own (a finer rest garment, the truth's own
cloth, the newton-vbd simulator) against ``--mode appearance`` (the truth on the run's own geometry); both modes
recorded in metrics.json; bad modes refused with one clear error.

The end-to-end cases are slow-marked: a run of the tiny demo evaluated in both modes, and a run on the body fitted to
the demo's capture by the same motion, whose truth is the same simulation (shared: simulated once); it runs with few
substeps (``[stages.eval] truth_options``) to stay within minutes.
"""

from __future__ import annotations

import json
import math
import shutil
import time

import numpy as np
import pytest

from pgc.cli import main
from pgc.errors import PGCConfigError, PGCDataError
from pgc.pipeline.evaluate import VARIANTS, with_modes


def registry_with_newton():
    """The installed plugins, with pgc_newton's registered by hand where the installed distribution predates its
    entry point (an editable install made before it was added)."""
    import pgc_newton.register
    from pgc.registry import Registry

    registry = Registry.discover()
    if ("simulator", "newton-vbd") not in registry.implementations:
        registry.add_plugin(pgc_newton.register, "newton")
    return registry


def test_a_bad_mode_gets_one_clear_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["eval", "RUN", "--gt", "CAPTURE", "--mode", "geometry"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --mode: invalid choice: 'geometry'" in err and "appearance" in err and "independent" in err
    from pgc.pipeline.independent import check_mode

    with pytest.raises(PGCConfigError, match="eval mode 'geometry' is unknown; use one of: appearance, independent"):
        check_mode("geometry")


def _result(mode: str, psnr: float, light: str = "capture") -> dict:
    result = {"frames": [0, 5], "cameras": ["cam000"], "light": {"kind": light}, "mode": mode,
              "render_inputs": {"garment.npz": "a", "body.npz": "b"}}
    for key in VARIANTS:
        result[key] = {"psnr": psnr, "per_frame": [{"frame": 0, "psnr": psnr}, {"frame": 5, "psnr": psnr}]}
    return result


def test_metrics_keep_each_mode_of_the_same_renders(tmp_path):
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps(with_modes(path, _result("appearance", 20.0))))
    doc = with_modes(path, _result("independent", 15.0))
    assert doc["mode"] == "appearance" and doc["hybrid"]["psnr"] == 20.0  # the top level stays appearance
    assert doc["modes"]["appearance"]["hybrid"] == {"psnr": 20.0}
    assert doc["modes"]["independent"]["pbr_only"] == {"psnr": 15.0}
    path.write_text(json.dumps(doc))
    again = with_modes(path, _result("appearance", 21.0))  # appearance again: the independent means stay
    assert again["hybrid"]["psnr"] == 21.0 and again["modes"]["independent"]["hybrid"]["psnr"] == 15.0
    relit = with_modes(path, _result("independent", 9.0, light="envmap"))  # other renders: nothing kept
    assert relit["mode"] == "independent" and set(relit["modes"]) == {"independent"}
    path.write_text("{not json")
    assert set(with_modes(path, _result("appearance", 20.0))["modes"]) == {"appearance"}


TRUTH_OPTIONS = "truth_options = {substeps = 2, iterations = 2, settle_frames = 2}\n"


@pytest.fixture(scope="module")
def arms_up(tiny_demo, tmp_path_factory):
    """A copy of the tiny demo's arms-up run evaluated in appearance mode, then in independent mode (its truth
    simulated with newton-vbd, timed): the file's two end-to-end tests share it, the second's run on the fitted
    body moving by the same motion, so needing the same truth simulation."""
    from pgc.pipeline.demo import demo_config
    from pgc.pipeline.evaluate import evaluate_run

    root = tmp_path_factory.mktemp("arms_up")
    run, capture = root / "run", tiny_demo / "capture"
    shutil.copytree(tiny_demo / "runs" / "arms-up", run)
    (run / "metrics.json").unlink()
    config = root / "eval.toml"
    config.write_text("[stages.eval]\n" + TRUTH_OPTIONS)
    registry = registry_with_newton()
    cfg = demo_config("tiny", config, registry=registry)

    appearance = evaluate_run(run, capture, cfg, mode="appearance")
    start = time.perf_counter()
    independent = evaluate_run(run, capture, cfg, mode="independent", registry=registry)
    first = time.perf_counter() - start
    return {"run": run, "capture": capture, "cfg": cfg, "registry": registry, "appearance": appearance,
            "independent": independent, "first": first,
            "truth_sim": sorted((run / "gt" / "truth_sim").iterdir())}


@pytest.mark.slow
def test_independent_truth_is_simulated_on_its_own_and_both_modes_are_recorded(arms_up, tmp_path):
    from pgc.io.mesh import read_mesh
    from pgc.pipeline.evaluate import evaluate_run

    run, capture, cfg, registry = arms_up["run"], arms_up["capture"], arms_up["cfg"], arms_up["registry"]
    appearance, independent, first = arms_up["appearance"], arms_up["independent"], arms_up["first"]

    figures = independent["truth_simulation"]
    assert figures["simulator"] == "newton-vbd" and figures["resolution_factor"] == 2.0
    assert figures["options"]["substeps"] == 2 and figures["options"]["density"] == 0.2  # the truth's own cloth
    capture_vertices = len(read_mesh(capture / "ground_truth" / "garment.obj").vertices)
    assert figures["rest_vertices"] > 3 * capture_vertices  # edges half as long: about 4x the vertices
    for result in (appearance, independent):
        for key in VARIANTS:
            assert all(math.isfinite(result[key][m]) for m in ("psnr", "ssim", "fsim", "lpips"))
    assert all(abs(appearance[k]["psnr"] - independent[k]["psnr"]) > 1e-3 for k in VARIANTS)

    doc = json.loads((run / "metrics.json").read_text())
    assert doc["mode"] == "appearance" and doc["hybrid"]["psnr"] == appearance["hybrid"]["psnr"]
    assert doc["modes"]["independent"]["hybrid"]["lpips"] == independent["hybrid"]["lpips"]
    assert doc["modes"]["independent"]["truth_simulation"]["simulator"] == "newton-vbd"
    assert len(list((run / "gt" / "truth_sim").glob("*.npz"))) == 1

    start = time.perf_counter()  # cached: the truth simulation and its renders
    again = evaluate_run(run, capture, cfg, mode="independent", registry=registry)
    assert time.perf_counter() - start < 0.5 * first
    assert again["hybrid"] == independent["hybrid"]

    images = tmp_path / "images"
    images.mkdir()
    with pytest.raises(PGCDataError, match="cannot be evaluated in mode 'independent'"):
        evaluate_run(run, images, cfg, mode="independent", registry=registry)
    sim = np.load(next((run / "gt" / "truth_sim").glob("*.npz")))
    assert sim["vertices"].shape[1] == figures["rest_vertices"] and np.all(np.isfinite(sim["vertices"]))


@pytest.mark.slow
def test_a_run_on_the_fitted_body_is_judged_against_a_truth_on_the_true_body(tiny_demo, arms_up, tmp_path, capsys):
    """``pgc reconstruct --body fit`` on the tiny demo's capture (its stages reused: only the body fit runs), a
    run on that body by the demo run's arms-up motion, appearance mode refused in one line, independent mode judged
    against the truth simulated on the true body moved by the run's motion: the very truth simulation of the demo's
    own arms-up run (``arms_up``: the same cache key, so the same file, which is found and not simulated again), the
    body and the mode in metrics.json."""
    from pgc.pipeline.demo import demo_config
    from pgc.pipeline.evaluate import evaluate_run
    from importlib import resources

    from pgc.pipeline.independent import truth_body_motion

    capture, asset, run = tiny_demo / "capture", tmp_path / "asset", tmp_path / "run"
    config = tmp_path / "fit.toml"
    preset = (resources.files("pgc") / "presets" / "demo_tiny.toml").read_text()  # the demo's stages, reused
    assert preset.count("[stages.eval]\n") == 1
    config.write_text(preset.replace("[stages.eval]\n", "[stages.eval]\n" + TRUTH_OPTIONS)
                      + "\n[stages.body_fit]\niterations = 60\nviews = 4\n")
    shutil.copytree(tiny_demo / "asset" / "stages", asset / "stages")
    common = ["--config", str(config), "--quiet"]
    assert main(["reconstruct", str(capture), "--out", str(asset), "--body", "fit", "--json", *common]) == 0
    assert json.loads(capsys.readouterr().out)["body"] == "fit"
    seconds = json.loads((asset / "timings.json").read_text())["seconds"]
    assert seconds["body_fit"] > 0 and seconds["mesh"] == seconds["material"] == 0.0  # only the body fit ran
    assert (asset / "body_fit" / "body.json").is_file()
    assert main(["animate", str(asset), "--motion", "arms-up", "--out", str(run), *common]) == 0
    assert json.loads((run / "run.json").read_text())["body"] == "fit"
    assert main(["render", str(run), *common]) == 0

    capsys.readouterr()
    assert main(["eval", str(run), "--gt", str(capture), *common]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "--mode independent" in err
    assert not (run / "metrics.json").exists()

    truth = truth_body_motion(run, capture)  # the demo's arms-up on the true body, not the run's fitted one
    demo_body = np.load(tiny_demo / "runs" / "arms-up" / "body.npz")["vertices"]
    np.testing.assert_allclose(truth.vertices, demo_body, atol=1e-5)
    assert np.abs(np.load(run / "body.npz")["vertices"] - demo_body).max() > 1e-3

    shared = arms_up["truth_sim"]  # the demo run's truth simulation, its .json figures and its .npz
    assert sorted(p.suffix for p in shared) == [".json", ".npz"]
    (run / "gt" / "truth_sim").mkdir(parents=True, exist_ok=True)
    for path in shared:
        shutil.copy2(path, run / "gt" / "truth_sim" / path.name)
    registry = registry_with_newton()
    result = evaluate_run(run, capture, demo_config("tiny", config, registry=registry), mode="independent",
                          registry=registry)
    # the same truth simulation: found under the same key (a truth moved by the fitted body would have another key
    # and be simulated into a second file), its figures the demo run's
    assert sorted(p.name for p in (run / "gt" / "truth_sim").iterdir()) == [p.name for p in shared]
    assert result["truth_simulation"] == arms_up["independent"]["truth_simulation"]
    doc = json.loads((run / "metrics.json").read_text())
    assert doc["mode"] == result["mode"] == "independent" and doc["body"] == result["body"] == "fit"
    assert doc["modes"]["independent"]["truth_simulation"]["simulator"] == "newton-vbd"
    for key in VARIANTS:
        assert all(math.isfinite(result[key][m]) for m in ("psnr", "ssim", "fsim", "lpips"))
