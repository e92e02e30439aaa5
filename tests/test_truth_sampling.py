"""The ground truth's sampling (pgc.synth.frames): passes to a noise target, the noise estimate, the seeds."""

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.synth.frames import pass_seed, relative_noise, render_frames, sampling_tag


@pytest.fixture(scope="module")
def fleece(tmp_path_factory, default_scene_renderer, default_body_model):
    """A tiny capture of a fibre truth (fleece): the noisiest of the fabrics to path trace."""
    from pgc.synth.generate import generate
    from pgc.synth.ground_truth import read_ground_truth
    from pgc.io.capture import read_capture

    out = tmp_path_factory.mktemp("synth") / "fleece"
    generate(out, "tiny", garment="tshirt", fabric="fleece", seed=1, renderer=default_scene_renderer,
             body_model=default_body_model)
    return read_ground_truth(out), read_capture(out).cameras


def test_relative_noise_is_the_standard_error_of_the_mean_over_its_brightness():
    rng = np.random.default_rng(0)
    mean = rng.uniform(0.2, 0.8, (64, 64, 3))
    weight = np.zeros((64, 64))
    weight[8:56, 8:56] = 1.0
    sigma = 0.05
    for n in (2, 4, 16):
        passes = [mean + sigma * rng.standard_normal(mean.shape) for _ in range(n)]
        for p in passes:  # noise where the weight is 0 does not count
            p[:8] += 10.0 * rng.standard_normal(p[:8].shape)
        expected = sigma / np.sqrt(n) / mean[8:56, 8:56].mean()
        assert relative_noise(passes, weight) == pytest.approx(expected, rel=0.05)


def test_relative_noise_of_nothing_to_grade_is_zero_and_one_pass_is_refused():
    image = np.ones((8, 8, 3))
    assert relative_noise([image, 2 * image], np.zeros((8, 8))) == 0.0  # no garment in view
    assert relative_noise([0 * image, 0 * image], np.ones((8, 8))) == 0.0  # black garment
    with pytest.raises(ValueError, match="at least two passes"):
        relative_noise([image], np.ones((8, 8)))


def test_pass_seeds_keep_the_first_and_differ_from_each_other_and_other_views():
    bases = [s * 100003 + t * 1009 + c for s in range(2) for t in range(40) for c in range(8)]
    seeds = {pass_seed(b, k) for b in bases for k in range(16)}
    assert len(seeds) == len(bases) * 16
    assert all(pass_seed(b, 0) == b for b in bases)
    assert all(0 <= s < 2 ** 31 for s in seeds)


def test_sampling_tag_names_the_policy():
    assert sampling_tag(64) == "spp64"
    assert sampling_tag(64, 0.05, 1024) == "spp64-noise0.05-max1024"


def test_truth_passes_reach_the_target_and_the_estimate_is_the_real_error(fleece, default_scene_renderer):
    gt, cameras = fleece
    cam = cameras[:1]
    g, b = gt.garment.vertices[None], gt.body.vertices[None]

    def frame(spp, **kw):
        return render_frames(gt, g, b, cam, spp=spp, renderer=default_scene_renderer, **kw)[0]

    one = frame(4)
    assert one["spp"][0] == 4 and "noise" not in one  # one pass: its noise is not measured
    target = 0.05
    passes = frame(4, noise=target, max_spp=4096)
    assert passes["noise"][0] <= target and 8 <= passes["spp"][0] < 4096
    reference = frame(4096, seed=1)  # another seed: independent of every pass above
    w = passes["garment_mask"][0]
    error = ((passes["color"][0].astype(np.float64) - reference["color"][0]) ** 2).mean(-1)
    actual = np.sqrt((w * error).sum() / w.sum()) / ((w * reference["color"][0].mean(-1)).sum() / w.sum())
    assert 0.6 * passes["noise"][0] < actual < 1.4 * passes["noise"][0]
    capped = frame(4, noise=1e-4, max_spp=16)
    assert capped["spp"][0] == 16 and capped["noise"][0] > 1e-4
    np.testing.assert_array_equal(frame(4, noise=0.0)["color"], one["color"])  # one pass: as before


def test_truth_noise_target_outside_0_1_is_refused(fleece, default_scene_renderer):
    gt, cameras = fleece
    with pytest.raises(PGCDataError, match="noise 1.5 must be in"):
        render_frames(gt, gt.garment.vertices[None], gt.body.vertices[None], cameras[:1], noise=1.5,
                      renderer=default_scene_renderer)


@pytest.mark.slow
def test_eval_records_what_the_truth_spent_and_reached(tiny_demo, tmp_path):
    import json
    import shutil
    from pathlib import Path

    from pgc.cli import main

    tiny_config = Path(__file__).resolve().parents[1] / "pgc" / "presets" / "demo_tiny.toml"
    target = tmp_path / "target.toml"
    target.write_text(tiny_config.read_text().replace("gt_noise = 0.0", "gt_noise = 0.1\ngt_max_spp = 256"))
    for config, run in ((tiny_config, tmp_path / "one-pass"), (target, tmp_path / "to-target")):
        shutil.copytree(tiny_demo / "runs" / "spooky", run, ignore=shutil.ignore_patterns("gt", "relit"))
        assert main(["eval", str(run), "--gt", str(tiny_demo / "capture"), "--quiet", "--config", str(config)]) == 0
        sampling = json.loads((run / "metrics.json").read_text())["truth_sampling"]
        frames = json.loads((run / "render" / "render.json").read_text())["frames"]
        assert len(sampling["spp"]) == len(frames) and sampling["spp_per_pass"] == 16
        if config == tiny_config:
            assert sampling["noise"] is None and sampling["largest_noise"] is None
            assert {s for row in sampling["spp"] for s in row} == {16}
            continue
        for spent_row, noise_row in zip(sampling["spp"], sampling["noise"]):
            for spent, noise in zip(spent_row, noise_row):
                assert spent % 16 == 0 and 32 <= spent <= 256
                assert noise <= 0.1 or spent == 256
        assert sampling["largest_noise"] == max(max(row) for row in sampling["noise"])
