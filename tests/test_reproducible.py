"""The same inputs and config give byte-identical outputs: assets from `pgc reconstruct`, runs from
`pgc animate`."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.cli import main
from pgc.io.asset import write_asset

TINY = """
[reconstructor]
use = ["visual_hull"]
[simulator]
use = ["xpbd-native", "xpbd-torch"]
[stages.fit_splats]
iterations = 30
converge_every = 10
select_count = false
select_sh = false
max_sh_degree = 0
[stages.base_color]
texture_size = 32
num_views = 2
[stages.material]
max_iterations = 3
max_image_side = 16
eval_spp = 4
"""


def hashes(folder: Path, skip: tuple[str, ...] = (".pgc.lock", "timings.json")) -> dict[str, str]:
    """sha256 of every output file below ``folder`` (relative names); stage caches, the lock and the wall-clock
    timings (``timings.json``, a measurement of each run) left out."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in skip
            and "stages" not in p.relative_to(folder).parts}


def test_an_asset_written_twice_is_byte_identical(tmp_path):
    from test_hostile import tiny_asset

    write_asset(tmp_path / "a", tiny_asset())
    write_asset(tmp_path / "b", tiny_asset())
    assert hashes(tmp_path / "a") == hashes(tmp_path / "b") and len(hashes(tmp_path / "a")) >= 6


def test_two_animate_runs_give_identical_trajectories(tmp_path, capsys):
    from test_hostile import tiny_asset

    write_asset(tmp_path / "asset", tiny_asset())
    v = seamed_cube().vertices
    np.savez(tmp_path / "m.npz", vertices=np.stack([v + [0, 0.002 * t, 0] for t in range(6)]),
             faces=seamed_cube().faces, fps=30.0)
    (tmp_path / "c.toml").write_text(TINY)
    for run in ("r1", "r2"):
        assert main(["animate", str(tmp_path / "asset"), "--motion", str(tmp_path / "m.npz"), "--out",
                     str(tmp_path / run), "--config", str(tmp_path / "c.toml"), "--quiet"]) == 0
    a, b = hashes(tmp_path / "r1"), hashes(tmp_path / "r2")
    assert a["garment.npz"] == b["garment.npz"] and a["body.npz"] == b["body.npz"]


@pytest.mark.slow
def test_two_reconstructions_of_one_capture_are_byte_identical(tmp_path, capsys):
    assert main(["synth", str(tmp_path / "cap"), "--preset", "tiny", "--views", "4", "--resolution", "32",
                 "--spp", "4"]) == 0
    (tmp_path / "c.toml").write_text(TINY)
    for out in ("a1", "a2"):
        code = main(["reconstruct", str(tmp_path / "cap"), "--out", str(tmp_path / out), "--config",
                     str(tmp_path / "c.toml"), "--quiet"])
        assert code == 0, capsys.readouterr().err
    assert hashes(tmp_path / "a1") == hashes(tmp_path / "a2")
