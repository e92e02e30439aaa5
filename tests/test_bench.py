"""pgc bench: the matrix, the record schema, CSV round trip, reference ratios, plots and the HTML report."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest

from pgc.bench import records as rec
from pgc.bench.matrix import load_matrix
from pgc.bench.runner import run_bench
from pgc.cli import main
from pgc.errors import PGCConfigError, PGCDataError
from pgc.registry import default_registry
from pgc.roles.filter import Filter

SMALL = """
[filter]
implementations = ["opencv", "box"]
variants = { opencv = [{}, { method = "box3" }] }
tiny = { size = 24, kernels = [5, 9], repeats = 1 }

[brdf]
implementations = ["lambertian"]
tiny = { directions = 500, backends = ["numpy"], repeats = 1 }
"""


def _matrix(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "matrix.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    matrix = _matrix(out, SMALL)
    return out, run_bench(out / "run", "tiny", matrix)


def test_records_have_the_schema(small_run):
    out, records = small_run
    assert records == json.loads((out / "run" / "bench.json").read_text())
    rec.validate(records)
    assert {r["role"] for r in records} == {"filter", "brdf"}
    for r in records:
        assert set(rec.REQUIRED) <= set(r) and r["preset"] == "tiny"
        assert r["error_key"] in r["errors"] and all(k == k.lower() for k in r["errors"])
        assert r["seconds"] > 0 and math.isfinite(r["peak_mb"]) and "numpy" in r["versions"]
        assert all(math.isfinite(v) for v in r["errors"].values())
    refs = [r for r in records if r["settings"]["reference"]]
    assert {(r["role"], r["settings"]["case"]) for r in refs} == {
        ("filter", "24px k=5"), ("filter", "24px k=9"), ("brdf", "lambertian n=500")}
    assert all(r["x_reference"] == 1.0 for r in refs)
    for r in records:  # x reference is seconds over the reference of the same case
        base = next(b for b in refs if (b["role"], b["settings"]["case"]) == (r["role"], r["settings"]["case"]))
        assert r["x_reference"] == pytest.approx(r["seconds"] / base["seconds"])
    exact = [r for r in records if r["implementation"] == "opencv" and not r["settings"]["options"]]
    assert len(exact) == 2 and all(r["errors"]["max_abs"] < 1e-5 for r in exact)  # the contract's agreement
    box3 = [r for r in records if r["settings"]["options"] == {"method": "box3"}]
    assert box3 and all(r["errors"]["max_abs"] > 1e-3 for r in box3)  # an approximation: the error shows it


def test_plots_exist_per_role_with_two_or_more_implementations(small_run):
    out, _ = small_run
    assert (out / "run" / "plots" / "filter.png").stat().st_size > 10_000
    assert not (out / "run" / "plots" / "brdf.png").exists()  # one implementation on one backend
    page = (out / "run" / "bench.html").read_text()
    assert "plots/filter.png" in page and "x reference" in page and "opencv[method=box3]" in page


def test_csv_round_trips(small_run, tmp_path):
    _, records = small_run
    failed = dict(records[0], failed="RuntimeError: boom", errors={}, seconds=float("nan"), x_reference=None)
    rows = records + [failed]
    rec.write_csv(tmp_path / "b.csv", rows)
    back = rec.read_csv(tmp_path / "b.csv")
    assert len(back) == len(rows)
    for a, b in zip(rows, back):
        for key in ("role", "implementation", "preset", "settings", "peak_mb", "errors", "versions",
                    "x_reference", "detail", "error_key", "label"):
            assert b[key] == a[key], key
        assert b["seconds"] == a["seconds"] or (math.isnan(a["seconds"]) and math.isnan(b["seconds"]))
        assert b.get("failed") == a.get("failed")


def test_report_re_renders_from_bench_json_alone(small_run, tmp_path):
    out, records = small_run
    shutil.copy(out / "run" / "bench.json", tmp_path / "bench.json")
    assert main(["bench", "--report", str(tmp_path), "--quiet"]) == 0
    assert (tmp_path / "plots" / "filter.png").is_file() and (tmp_path / "bench.html").is_file()
    assert rec.read_csv(tmp_path / "bench.csv")[0]["implementation"] == records[0]["implementation"]


def test_report_of_a_missing_or_bad_bench_json_is_a_clear_error(tmp_path, capsys):
    assert main(["bench", "--report", str(tmp_path)]) == 2
    assert "no bench.json" in capsys.readouterr().err
    (tmp_path / "bench.json").write_text(json.dumps([{"role": "filter"}]))
    with pytest.raises(PGCDataError, match="record 0 has no 'implementation'"):
        rec.read_json(tmp_path / "bench.json")


def test_reference_ratio_is_per_role_and_case():
    def r(role, case, seconds, reference=False):
        return {"role": role, "settings": {"case": case, "reference": reference}, "seconds": seconds}

    rows = [r("a", "x", 2.0, True), r("a", "x", 1.0), r("a", "y", 4.0), r("b", "x", 3.0, True), r("b", "x", 6.0)]
    rec.add_reference_ratios(rows)
    assert [x["x_reference"] for x in rows] == [1.0, 0.5, None, 1.0, 2.0]


@pytest.mark.parametrize("text, message", [
    ("[nosuchrole]\n", "unknown role 'nosuchrole'; roles with a bench workload: reconstructor"),
    ("[filter]\nimplementations = ['nope']\n", "no filter named 'nope'; registered: box, jax, opencv, torch"),
    ("[filter]\nimplementations = ['opencv']\nvariants = { torch = [{}] }\n", "variants for 'torch'"),
    ("[filter]\nimplementations = ['opencv']\nvariants = { opencv = [{ method = 'fft' }] }\n",
     "invalid options for filter 'opencv'"),
    ("[filter]\nimplementation = '*'\n", "unknown keys ['implementation']"),
])
def test_bad_matrix_fails_before_work_listing_what_exists(tmp_path, text, message):
    with pytest.raises(PGCConfigError, match="matrix.toml") as exc:
        run_bench(tmp_path / "out", "tiny", _matrix(tmp_path, text))
    assert message in str(exc.value)
    assert not (tmp_path / "out").exists()


def test_unknown_role_on_the_command_line_is_a_clear_error(tmp_path, capsys):
    assert main(["bench", "--role", "renderer", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "unknown role 'renderer'" in capsys.readouterr().err
    matrix = _matrix(tmp_path, SMALL)
    assert main(["bench", "--config", str(matrix), "--role", "metric", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "no table for role(s) metric; the matrix has: filter, brdf" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_default_matrix_covers_every_installed_implementation():
    registry = default_registry()
    plans = {p.role: p for p in load_matrix(None, registry, "tiny")}
    roles = {i.role for i in registry.list()}
    assert roles <= set(plans)
    for role in roles:
        available = {i.name for i in registry.list(role) if i.available}
        assert {run.implementation for run in plans[role].runs} == available
        assert plans[role].workload, f"no tiny workload for {role}"


@pytest.mark.slow
def test_pgc_bench_tiny_end_to_end(tmp_path, capsys):
    """The command on the tiny preset for two roles: records, CSV, one plot per role, HTML, JSON output."""
    out = tmp_path / "b"
    assert main(["bench", "--preset", "tiny", "--role", "metric", "splat_renderer", "--out", str(out),
                 "--quiet", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    records = rec.read_json(out / "bench.json")
    assert printed == records
    assert {r["implementation"] for r in records if r["role"] == "metric"} >= {"psnr", "ssim", "numpy-psnr"}
    assert {r["implementation"] for r in records if r["role"] == "splat_renderer"} >= {"torch", "jax"}
    splats = [r for r in records if r["role"] == "splat_renderer" and not r["settings"]["reference"]]
    assert all(r["errors"]["max_abs"] < 1e-4 for r in splats)  # both agree with the float64 reference
    for role in ("metric", "splat_renderer"):
        assert (out / "plots" / f"{role}.png").is_file()
    assert len(rec.read_csv(out / "bench.csv")) == len(records)


class BrokenFilter(Filter):
    """A filter whose low-pass always raises (to check that a failing run is recorded, not fatal)."""

    def lowpass(self, image, alpha, kernel_size):
        raise RuntimeError("broken on purpose")


def test_a_failing_implementation_is_recorded_and_the_others_still_run(tmp_path):
    from pgc.registry import ImplementationSpec, Registry

    registry = Registry.discover()
    registry.add(ImplementationSpec(role="filter", name="broken", factory=f"{__name__}:BrokenFilter",
                                    description="test"))
    matrix = _matrix(tmp_path, "[filter]\nimplementations = ['broken', 'opencv']\ntiny = { size = 16, kernels = [5] }\n")
    records = run_bench(tmp_path / "out", "tiny", matrix, registry=registry)
    broken = [r for r in records if r["implementation"] == "broken"]
    assert len(broken) == 1 and broken[0]["failed"] == "RuntimeError: broken on purpose"
    assert broken[0]["errors"] == {} and broken[0]["x_reference"] is None
    detail = json.loads((tmp_path / "out" / broken[0]["detail"]).read_text())
    assert "broken on purpose" in "".join(detail["traceback"])
    ok = [r for r in records if r["implementation"] == "opencv"]
    assert len(ok) == 1 and ok[0]["errors"]["max_abs"] < 1e-5
    assert "broken on purpose" in (tmp_path / "out" / "bench.html").read_text()


@pytest.mark.slow
def test_bench_on_a_local_cluster_gives_the_in_process_records(small_run, tmp_path):
    """--scheduler local:2: one task per role on two worker processes, merged into the same bench.json."""
    _, here = small_run
    matrix = _matrix(tmp_path, SMALL)
    records = run_bench(tmp_path / "run", "tiny", matrix, scheduler="local:2")
    assert records == json.loads((tmp_path / "run" / "bench.json").read_text())
    key = [(r["role"], r["label"], r["settings"]["case"]) for r in records]
    assert key == [(r["role"], r["label"], r["settings"]["case"]) for r in here]
    for a, b in zip(records, here):
        assert a["errors"] == pytest.approx(b["errors"], rel=1e-6, abs=1e-9)
    assert (tmp_path / "run" / "plots" / "filter.png").is_file()
