"""The example third-party plugin: installed, listed by `pgc plugins`, selected in a config, conformant."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from pgc import config
from pgc.cli import main
from pgc.registry import Registry
from pgc.testing.conformance import FilterConformance
from pgc_example_plugin.box_blur import BoxBlurFilter, box_sum


def _pgc(capsys, *args: str) -> subprocess.CompletedProcess:
    """Run ``pgc ARGS`` in this process; returns code, stdout and stderr like subprocess.run."""
    code = main(list(args))
    captured = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, captured.out, captured.err)


def test_listed_by_pgc_plugins(capsys):
    out = _pgc(capsys, "plugins", "--json")
    assert out.returncode == 0, out.stderr
    rows = [r for r in json.loads(out.stdout) if r["name"] == "box"]
    assert rows == [{"role": "filter", "name": "box", "provider": "pgc-example-plugin", "plugin": "example",
                     "available": True, "reason": None,
                     "description": "alpha-aware separable box blur in numpy (example third-party plugin)"}]


def test_selected_in_a_config(tmp_path, capsys):
    cfg_file = tmp_path / "run.toml"
    cfg_file.write_text('[filter]\nuse = "box"\n[filter.box]\npasses = 3\n')
    out = _pgc(capsys, "config", "validate", str(cfg_file))
    assert out.returncode == 0 and "filter=box" in out.stdout, out.stderr
    cfg = config.load(cfg_file, registry=Registry.discover())
    impl = cfg.create("filter")
    assert isinstance(impl, BoxBlurFilter) and impl.options.passes == 3
    shown = _pgc(capsys, "config", "show", str(cfg_file))
    assert '[filter.box]\npasses = 3' in shown.stdout


def test_bad_option_for_the_plugin(tmp_path, capsys):
    cfg_file = tmp_path / "run.toml"
    cfg_file.write_text('[filter]\nuse = "box"\n[filter.box]\npasses = 0\n')
    out = _pgc(capsys, "config", "validate", str(cfg_file))
    assert out.returncode == 2
    assert "[filter.box]: invalid options for filter 'box'" in out.stderr and "option 'passes'" in out.stderr


def test_box_sum_known_values():
    x = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    np.testing.assert_array_equal(box_sum(x, 1, 0), [3, 6, 9, 12, 9])
    np.testing.assert_array_equal(box_sum(x, 10, 0), [15] * 5)


def test_impulse_response_with_renormalised_border():
    image = np.zeros((1, 7, 1), np.float32)
    image[0, 3] = 1.0
    out = BoxBlurFilter().lowpass(image, np.ones((1, 7), np.float32), 3)
    np.testing.assert_allclose(out[0, :, 0], [0, 0, 1 / 3, 1 / 3, 1 / 3, 0, 0], atol=1e-7)
    edge = np.zeros((1, 4, 1), np.float32)
    edge[0, 0] = 1.0  # at the border the window holds 2 pixels: weight 1/2
    np.testing.assert_allclose(BoxBlurFilter().lowpass(edge, np.ones((1, 4), np.float32), 3)[0, :, 0],
                               [0.5, 1 / 3, 0, 0], atol=1e-7)


def test_multi_pass_variance():
    """n passes of a k-pixel box: an impulse spreads with variance n (k^2 - 1) / 12 per axis."""
    image = np.zeros((41, 41, 1), np.float32)
    image[20, 20] = 1.0
    out = BoxBlurFilter({"passes": 3}).lowpass(image, np.ones((41, 41), np.float32), 5)[..., 0]
    x = np.arange(41) - 20
    assert out.sum() == pytest.approx(1.0, abs=1e-6)
    assert (out.sum(axis=0) * x ** 2).sum() == pytest.approx(3 * (25 - 1) / 12, rel=1e-5)


class TestBoxBlurConformance(FilterConformance):
    @pytest.fixture(params=[1, 3], ids=["1pass", "3passes"])
    def implementation(self, request):
        return BoxBlurFilter({"passes": request.param})
