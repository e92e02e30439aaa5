"""The sweep's paired comparison (``[table] reference``): margins signed by each metric's direction, pairs that
differ only in the compared field, the reference's spread between seeds, and the outputs (the file's validation of
``reference`` is in test_sweep.py)."""

from __future__ import annotations

import itertools
import json

import pytest

from pgc.sweep.paired import margin, metric_directions, paired_cells, paired_grid
from pgc.sweep.spec import Table

DIRECTIONS = {"psnr": True, "lpips": False}


def _record(seed: int, light: str, variant: str, psnr: float, lpips: float, **extra) -> dict:
    return {"scene": f"tee-seed{seed}", "configuration": "default", "motion": "walk", "light": light,
            "mode": "appearance", "variant": variant, "preset": "tiny", "garment": "tshirt", "fabric": "knit",
            "seed": seed, "framing": None, "detail": None, "fit": None, "looseness": None, "views": None,
            "metrics": {"psnr": psnr, "lpips": lpips}, **extra}


def test_margin_is_positive_when_the_reference_is_better_in_either_direction():
    assert margin(0.05, 0.10, higher_is_better=False) == pytest.approx(0.5)
    assert margin(0.10, 0.05, higher_is_better=False) == pytest.approx(-1.0)
    assert margin(20.0, 16.0, higher_is_better=True) == pytest.approx(0.25)
    assert margin(1.0, 0.0, higher_is_better=True) is None


def _records() -> list[dict]:
    """hybrid vs pbr_only on two seeds and two lights; hybrid LPIPS 0.04 / 0.05 (seeds 0 / 1), pbr_only 0.05 /
    0.05, so the margins are 20 % and 0 %; the hybrid's seed spread is 0.01 / 0.045 = 22.2 %."""
    out = []
    for seed, light in itertools.product((0, 1), ("capture", "low-key")):
        out.append(_record(seed, light, "hybrid", 20.0 + seed, (0.04, 0.05)[seed]))
        out.append(_record(seed, light, "pbr_only", 19.0 + seed, 0.05))
    return out


def test_paired_cells_pair_record_by_record_and_report_the_seed_spread():
    cells = paired_cells(_records(), Table(rows=["variant"], columns=["light"], reference={"variant": "hybrid"}),
                         DIRECTIONS)
    by = {(c["column"]["light"], c["metric"]): c for c in cells}
    assert set(by) == {(light, m) for light in ("capture", "low-key") for m in DIRECTIONS}
    lpips = by["capture", "lpips"]
    assert lpips["against"] == "pbr_only" and lpips["pairs"] == 2 and lpips["wins"] == 1
    assert lpips["margin"] == pytest.approx(0.1) and lpips["worst"] == pytest.approx(0.0)
    assert lpips["seed_spread"] == pytest.approx(0.01 / 0.045) and lpips["seed_groups"] == 1
    assert lpips["beyond_spread"] is False
    psnr = by["low-key", "psnr"]
    assert psnr["margin"] == pytest.approx((1 / 19 + 1 / 20) / 2) and psnr["wins"] == 2
    assert psnr["seed_spread"] == pytest.approx(1 / 20.5) and psnr["beyond_spread"] is True


def test_unpaired_failed_and_filtered_records_are_left_out():
    records = _records()
    records.append(_record(2, "capture", "pbr_only", 10.0, 0.9))  # no hybrid on seed 2: no pair
    records.append(_record(3, "capture", "hybrid", 0.0, 0.0, failed="boom"))
    records.append(_record(3, "capture", "pbr_only", 10.0, 0.9))
    records.append(_record(4, "capture", "hybrid", float("nan"), 0.04))
    records.append(_record(4, "capture", "pbr_only", 19.0, 0.05))
    table = Table(rows=["variant"], columns=["light"], reference={"variant": "hybrid"}, where={"light": ["capture"]})
    cells = {c["metric"]: c for c in paired_cells(records, table, DIRECTIONS)}
    assert {c["column"]["light"] for c in cells.values()} == {"capture"}
    assert cells["psnr"]["pairs"] == 2 and cells["lpips"]["pairs"] == 3
    assert cells["lpips"]["margin"] == pytest.approx(0.4 / 3)


def test_a_configuration_can_be_the_reference_and_no_reference_gives_no_cells():
    records = [_record(0, "capture", "pbr_only", 20.0, 0.04) | {"configuration": "sheen"},
               _record(0, "capture", "pbr_only", 19.0, 0.05) | {"configuration": "lambertian"}]
    (cell,) = paired_cells(records, Table(reference={"configuration": "sheen"}), {"lpips": False})
    assert cell["against"] == "lambertian" and cell["margin"] == pytest.approx(0.2)
    assert cell["seed_spread"] is None and cell["beyond_spread"] is None
    assert paired_cells(records, Table(), {"lpips": False}) == []


def test_paired_grid_reads_as_margin_wins_and_spread():
    cells = paired_cells(_records(), Table(columns=["light"], reference={"variant": "hybrid"}), DIRECTIONS)
    head, grid = paired_grid(cells)
    assert head == ["hybrid vs variant", "configuration", "light", "psnr", "lpips"]  # the table's rows and columns
    assert grid[0][:3] == ["pbr_only", "default", "capture"]
    assert grid[0][4] == "+10.0 % (1/2) <= 22.2 %"
    assert paired_grid([]) == ([], [])


def test_metric_directions_come_from_the_registered_metrics():
    directions = metric_directions(["psnr", "ssim", "lpips", "mesh_seconds"])
    assert directions == {"psnr": True, "ssim": True, "lpips": False}


def test_the_outputs_carry_the_paired_table(tmp_path):
    from pgc.sweep.table import text_table, write_outputs

    table = Table(rows=["variant"], columns=["light"], reference={"variant": "hybrid"})
    records = _records()
    for r in records:
        r |= {"figures": {}, "seconds": {"render": 1.0}}
    cells = paired_cells(records, table, DIRECTIONS)
    write_outputs(tmp_path, "t", records, table, {}, cells)
    assert json.loads((tmp_path / "paired.json").read_text()) == json.loads(json.dumps(cells))
    page = (tmp_path / "sweep.html").read_text()
    assert "<h2>Paired</h2>" in page and "+10.0 % (1/2) &lt;= 22.2 %" in page
    text = text_table(records, table, cells)
    assert "Paired against the reference" in text and "+10.0 % (1/2) <= 22.2 %" in text
