"""The report in a real browser: headless Chromium loads every picture and logs nothing to the console.

A session fixture builds a tiny demo (pgc demo --preset tiny) and a relit copy of one run
(pgc render --rotate-light). The browser test skips only where Chromium is absent and CI is not set.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pgc.cli import main

CHROMIUM = next((c for c in ("chromium", "chromium-browser", "google-chrome") if shutil.which(c)), None)


@pytest.fixture(scope="session")
def demo(tiny_demo) -> Path:
    return tiny_demo


@pytest.fixture(scope="session")
def relit(demo) -> Path:
    run = demo.parent / "relit"
    shutil.copytree(demo / "runs" / "spooky", run)
    sky = demo / "capture" / "ground_truth" / "envmaps" / "sky.exr"
    assert main(["render", str(run), "--light", str(sky), "--rotate-light", "--quiet"]) == 0
    assert main(["report", str(run)]) == 0
    return run


def _browser() -> str:
    if CHROMIUM is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail("CI is set but no chromium is installed: the report's browser test must run in CI")
        pytest.skip("chromium is not installed (apt-get install chromium); set CI=true to make this a failure")
    return CHROMIUM


def _chromium(page: Path, *flags: str) -> subprocess.CompletedProcess:
    cmd = [_browser(), "--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
           "--hide-scrollbars",
           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", *flags, page.resolve().as_uri()]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def _check_in_browser(page: Path, shot: Path) -> dict[str, int]:
    dom = _chromium(page, "--dump-dom")
    assert dom.returncode == 0, dom.stderr[-2000:]
    # the 3D view's WebGL notes under virtual time are left to tests/test_report_viewer.py (real time)
    console = [line for line in dom.stderr.splitlines() if (":CONSOLE" in line or "Uncaught" in line)
               and "report/model-viewer.min.js" not in line and "GL Driver Message" not in line]
    assert not console, console  # no script error, no console message at all
    found = re.search(r'id="load-check" data-loaded="(\d+)" data-total="(\d+)"', dom.stdout)
    assert found, "the load check did not run (script blocked?)"
    loaded, total = int(found[1]), int(found[2])
    assert loaded == total == page.read_text().count("<img "), (loaded, total)
    snap = _chromium(page, f"--screenshot={shot}", "--window-size=1400,2600")
    assert snap.returncode == 0 and shot.is_file(), snap.stderr[-2000:]
    return {"loaded": loaded, "total": total}


@pytest.mark.slow
def test_demo_report_loads_every_picture_in_chromium(demo, tmp_path):
    page = demo / "report.html"
    html = page.read_text()
    assert not re.search(r"""(src|href)=['"](https?:)?//""", html)  # self-contained: no network
    seen = _check_in_browser(page, tmp_path / "report.png")
    assert seen["total"] >= 3 * 11  # per motion: 4 strip, 3 heatmaps + scale, 2 decomposition, 1 animation
    shot = np.asarray(Image.open(tmp_path / "report.png").convert("L"), float)
    assert shot.std() > 10  # a page with pictures, not a blank one
    # every reported picture exists; crops are whole-pixel enlargements (k x k blocks)
    names = re.findall(r"src='(report/[^']+)'", html)
    assert all((demo / n).is_file() for n in names)
    crop = np.asarray(Image.open(demo / next(n for n in names if n.endswith("_gt.png"))))
    k = int(re.search(r"enlarged x(\d+)", html)[1])
    assert k >= 2 and crop.shape[0] % k == 0
    np.testing.assert_array_equal(np.repeat(np.repeat(crop[::k, ::k], k, 0), k, 1), crop)
    frames = len(json.loads((demo / "runs" / "goalpost" / "render" / "render.json").read_text())["frames"])
    with Image.open(demo / "report" / "goalpost_loop.webp") as anim:
        assert anim.n_frames == frames and anim.info.get("loop") == 0
    size = int(re.search(r"\((\d+) KiB in all\)", html)[1])
    on_disk = page.stat().st_size + sum(p.stat().st_size for p in (demo / "report").iterdir())
    assert abs(size * 1024 - on_disk) < 2048 and on_disk < 3 * 2**20


@pytest.mark.slow
def test_relit_run_report_shows_the_light_rotation(relit, tmp_path):
    page = relit / "report.html"
    html = page.read_text()
    assert "Relighting" in html and html.count("light at ") >= 2 and "spooky_relight.webp" in html
    # its cached truth is under the capture light: no heatmaps for the turning light (its relit runs, copied with
    # it, have their own truth and heatmaps)
    assert not re.search(r"src='report/spooky_\d+_\w+_error\.png'", html) and "No ground truth under this" in html
    assert "src='report/low-key_spooky_" in html and "_error.png" in html
    names = re.findall(r"src='(report/spooky_relight_\d+\.png)'", html)
    first, last = (np.asarray(Image.open(relit / n), float) for n in (names[0], names[-1]))
    assert np.abs(first - last).mean() > 1.0  # the light turned: the garment's shading changed
    _check_in_browser(page, tmp_path / "relit.png")


@pytest.mark.slow
def test_report_command_rebuilds_and_sweeps_stale_pictures(demo, capsys):
    stale = demo / "report" / "old_picture.png"
    stale.write_bytes(b"x")
    assert main(["report", str(demo), "--json"]) == 0
    assert '"bytes"' in capsys.readouterr().out and not stale.exists()
    html = (demo / "report.html").read_text()
    assert "Under novel lights" in html and "Metrics per light" in html


def test_report_errors_name_the_folder_and_the_fix(tmp_path, capsys):
    assert main(["report", str(tmp_path / "nope")]) == 2
    assert "nope" in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "pgc demo --out" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    assert "examples:" in capsys.readouterr().out


def test_bench_records_chart_speed_against_error(tmp_path):
    from pgc.errors import PGCDataError
    from pgc.pipeline.report import _bench_records
    from pgc.pipeline.report_figures import bench_chart

    records = [{"role": "filter", "implementation": name, "label": name, "seconds": s, "error_key": "max_abs",
                "errors": {"max_abs": e}} for name, s, e in (("numpy", 0.01, 1e-6), ("opencv", 0.001, 1e-3))]
    records.append({"role": "filter", "implementation": "broken", "seconds": None, "errors": {}})
    (tmp_path / "bench.json").write_text(json.dumps(records))
    loaded = _bench_records(tmp_path)
    assert len(loaded) == 3
    assert bench_chart(tmp_path / "bench.svg", loaded)
    svg = (tmp_path / "bench.svg").read_text()
    assert "opencv" in svg and "numpy" in svg and "broken" not in svg and "max_abs" in svg
    assert not bench_chart(tmp_path / "none.svg", records[2:]) and not (tmp_path / "none.svg").exists()
    with pytest.raises(PGCDataError, match="pgc bench --out"):
        _bench_records(tmp_path / "elsewhere")


def test_detail_windows_find_the_textured_patches_inside_the_garment():
    from pgc.pipeline.report_figures import detail_windows

    rng = np.random.default_rng(0)
    img = np.full((120, 160, 3), 0.4)
    yy, xx = np.mgrid[0:120, 0:160]
    ribs = 0.4 + 0.3 * ((xx // 2) % 2)[..., None]          # 2 px ribs: the finest detail, top left
    img[20:60, 20:60] = ribs[20:60, 20:60]                    # on the half-window grid (20 px)
    img[60:100, 100:140] += rng.normal(0, 0.05, (40, 40, 3))  # weaker texture, bottom right
    img[80:120, 0:40] = ribs[80:120, 0:40]                    # strong detail outside the garment: never chosen
    inside = np.zeros((120, 160), bool)
    inside[:, 5:] = True
    inside[75:, :45] = False
    wins = detail_windows(img, inside, size=40, count=3)
    assert wins[0] == (20, 60, 20, 60) and wins[1] == (60, 100, 100, 140)
    for a, b, c, d in wins:
        assert b - a == d - c == 40 and inside[a:b, c:d].all()
    for i, (a, b, c, d) in enumerate(wins):          # no two overlap
        for e, f, g, h in wins[i + 1:]:
            assert b <= e or f <= a or d <= g or h <= c
    assert detail_windows(img, np.zeros((120, 160), bool)) == []
    assert detail_windows(img[:30, :30], np.ones((30, 30), bool), size=40) == []
