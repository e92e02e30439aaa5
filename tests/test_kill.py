"""`pgc animate` killed at 20 seeded random moments (SIGINT, SIGTERM, SIGKILL), resumed each time, ends with
the same files as an uninterrupted run, no orphan temporary folder and no held lock."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.io.asset import write_asset
from pgc.io.lock import is_locked

KILLS = 20
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)
CONFIG = '[simulator]\nuse = ["xpbd-native", "xpbd-torch"]\n'


def outputs(run: Path) -> dict[str, str]:
    """Hashes of the run's result files; run.json without its wall-clock figures (seconds, frames per second)."""
    out = {name: hashlib.sha256((run / name).read_bytes()).hexdigest() for name in ("garment.npz", "body.npz")}
    meta = json.loads((run / "run.json").read_text())
    for key in ("seconds", "frames_per_second"):
        meta["figures"].pop(key, None)
    out["run.json"] = json.dumps(meta, sort_keys=True)
    return out


def animate(tmp: Path, run: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "pgc.cli", "animate", str(tmp / "asset"), "--motion",
                             str(tmp / "m.npz"), "--out", str(run), "--config", str(tmp / "c.toml"), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_animate_killed_at_random_moments_resumes_to_the_uninterrupted_result(tmp_path):
    from test_hostile import tiny_asset

    write_asset(tmp_path / "asset", tiny_asset())
    v = seamed_cube().vertices
    np.savez(tmp_path / "m.npz", vertices=np.stack([v + [0, 0.002 * t, 0] for t in range(15)]),
             faces=seamed_cube().faces, fps=30.0)
    (tmp_path / "c.toml").write_text(CONFIG)
    start = time.perf_counter()
    ref = animate(tmp_path, tmp_path / "ref")
    assert ref.wait() == 0, ref.stderr.read()
    duration = time.perf_counter() - start
    expected = outputs(tmp_path / "ref")

    rng = np.random.default_rng(20261201)
    run = tmp_path / "run"
    killed = 0
    for i in range(KILLS):
        if i % 5 == 4:  # now and then a finished run, then an overwrite killed over it
            run_to_end = animate(tmp_path, run)
            assert run_to_end.wait() == 0, run_to_end.stderr.read()
            (run / "stages" / "animate" / "stage.json").unlink()  # force a recompute that the kill interrupts
        proc = animate(tmp_path, run)
        time.sleep(float(rng.uniform(0.0, duration)))
        sig = SIGNALS[i % len(SIGNALS)]
        proc.send_signal(sig)
        code = proc.wait()
        err = proc.stderr.read()
        if code != 0:
            killed += 1
            # 130: pgc's interrupt path; -SIGINT: the interpreter's own (a signal during start-up or shut-down)
            assert code in (130, -signal.SIGINT, -signal.SIGKILL, -sig), (sig, code, err)
            # a SIGINT that lands while the interpreter still imports (before pgc's handler) is Python's own
            assert "Traceback" not in err or code == -signal.SIGINT, err
    assert killed >= KILLS // 2, f"only {killed} of {KILLS} runs were interrupted before finishing"
    final = animate(tmp_path, run)
    assert final.wait() == 0, final.stderr.read()
    assert outputs(run) == expected
    assert not list((run / "stages").glob(".animate.*")), "orphan temporary stage folders left"
    assert not is_locked(run)
    assert os.listdir(run / "stages") == ["animate"]
