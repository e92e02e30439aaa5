"""Killed at random moments, resumed, nothing lost or mixed.

A tiny pipeline (``pgc synth``, ``reconstruct``, ``animate``, ``render``) is run once without interruption,
then again in the same folder killed at 20 seeded moments (SIGINT, SIGTERM and SIGKILL in turn), each run
resuming what the previous one left. The end state must hold the same bytes as the uninterrupted run, no
orphan temporary file or folder and no held lock.

The moments are aimed so that every stage is hit: each target is a phase of one command (its start-up, a
cached stage, or the writing of its output files), found by what the phase leaves on disk (the stage's
temporary folder ``.<stage>.<pid>.*``, the temporary files ``.<name>.<pid>.*.tmp*`` of atomic writes); the
signal follows at a seeded uniform delay within the phase's duration measured in the uninterrupted run. Delays
and durations are the command's CPU seconds, not wall seconds, so a kill lands at the same point of the
command's work however loaded the machine is (beside another pytest-xdist worker, say); the commands run at a
lower priority than the test, which watches for short phases (the writes) between 2 ms sleeps.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pgc.io.atomic import atomic_path, process_alive
from pgc.io.lock import LOCK_NAME, is_locked
from pgc.io.timings import TIMINGS, split_timings
from pgc.pipeline.cache import STAGE_META

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)
CONFIG = """
[reconstructor]
use = ["visual_hull"]
[reconstructor.visual_hull]
target_vertices = 1500
remesh_iterations = 2
uv_resolution = 128
[simulator]
use = ["xpbd-native", "xpbd-torch"]
[simulator.xpbd-native]
substeps = 5
iterations = 5
settle_frames = 2
blend_frames = 2
[stages.garment]
uv_resolution = 128
[stages.fit_splats]
iterations = 30
converge_every = 10
min_gaussians = 200
select_count = false
select_sh = false
max_sh_degree = 0
[stages.base_color]
texture_size = 32
num_views = 2
[stages.material]
max_iterations = 3
max_image_side = 32
eval_spp = 4
spp = 2
views_per_step = 2
[stages.animate]
seconds = 0.2
[stages.render]
views = 1
kernel_views = 1
texture_size = 32
frame_stride = 3
[stages.render.kernel]
mode = "fixed"
size = 5
"""
PIPELINE = ("synth", "reconstruct", "animate", "render")
PHASES = {
    "synth": {},
    "reconstruct": {**{s: f"asset/stages/.{s}.{{pid}}.*" for s in ("mesh", "garment", "fit_splats", "base_color",
                                                                    "material")},
                    "write": "asset/.*.{pid}.*.tmp*"},
    "animate": {"animate": "run/stages/.animate.{pid}.*", "write": "run/.*.{pid}.*.tmp*"},
    "render": {"render": "run/.render.{pid}.*"},
}
"""Per command, its phases in order and the glob of what each leaves on disk while it runs ({pid}: the
command's process)."""
STAGE_FOLDERS = {**{s: f"asset/stages/{s}" for s in PHASES["reconstruct"] if s != "write"},
                 "animate": "run/stages/animate", "render": "run/render"}
"""The folder of each cached stage."""
TARGETS = [("synth", "any"),
           ("reconstruct", "start"), ("reconstruct", "mesh"), ("reconstruct", "mesh"), ("reconstruct", "garment"),
           ("reconstruct", "fit_splats"), ("reconstruct", "base_color"), ("reconstruct", "material"),
           ("reconstruct", "write"), ("reconstruct", "overwrite"),
           ("animate", "start"), ("animate", "animate"), ("animate", "animate"), ("animate", "write"),
           ("animate", "overwrite"),
           ("render", "start"), ("render", "render"), ("render", "render"), ("render", "render"), ("render", "render")]
"""20 kills: 'any' is a moment of the whole command, 'start' its start-up (imports, input checks), 'overwrite'
the writing of the output files over a complete earlier result."""
POLL = 0.002
NICE = 5
"""How much lower the commands' priority is than the test's."""
TICK = os.sysconf("SC_CLK_TCK")
ATTEMPTS = 5
"""Tries per target: a phase can end before the signal (a write of a few milliseconds is not seen, a phase runs
faster than in the uninterrupted run); each try draws its delay from a range 4 times shorter."""


def argv(command: str, w: Path) -> list[str]:
    cfg = ["--config", str(w / "c.toml"), "--quiet"]
    return [sys.executable, "-m", "pgc.cli", *{
        "synth": ["synth", str(w / "cap"), "--preset", "tiny", "--views", "4", "--resolution", "32", "--spp", "4"],
        "reconstruct": ["reconstruct", str(w / "cap"), "--out", str(w / "asset"), *cfg],
        "animate": ["animate", str(w / "asset"), "--motion", "spooky", "--out", str(w / "run"), *cfg],
        "render": ["render", str(w / "run"), *cfg]}[command]]


def children_cpu() -> float:
    """CPU seconds of this process's waited-for subprocesses."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


class Command:
    """One command running in the background, its stderr in a file, watched for the phases it starts; times are
    the command's CPU seconds."""

    def __init__(self, command: str, w: Path, log: Path) -> None:
        self.command, self.w, self.log = command, w, log
        self.cpu_before = children_cpu()
        with open(log, "w") as err:
            self.proc = subprocess.Popen(argv(command, w), stdout=subprocess.DEVNULL, stderr=err, cwd=w.parent)
        # before the interpreter has started its threads (each thread has its own priority; new ones inherit it)
        os.setpriority(os.PRIO_PROCESS, self.proc.pid, os.getpriority(os.PRIO_PROCESS, 0) + NICE)
        self.seen: dict[str, float] = {}
        self.last_cpu = 0.0
        self.patterns: dict[str, tuple[Path, re.Pattern]] = {}
        """Per phase, the folder it leaves its files in and their names' pattern (a folder's listing and a
        match per poll: a third of the CPU of a glob per phase)."""
        for phase, pattern in PHASES[command].items():
            folder, _, name = pattern.format(pid=self.proc.pid).rpartition("/")
            self.patterns[phase] = (w / folder, re.compile(fnmatch.translate(name)))

    def cpu(self) -> float:
        """The command's CPU seconds so far (its threads and waited-for subprocesses; 10 ms steps)."""
        try:
            fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rpartition(")")[2].split()
            self.last_cpu = sum(int(f) for f in fields[11:15]) / TICK  # utime, stime, cutime, cstime
        except (OSError, ValueError):
            pass  # ended: its last reading
        return self.last_cpu

    def look(self, phases: list[str]) -> None:
        listings: dict[Path, list[str]] = {}
        for phase in phases:
            if phase in self.seen:
                continue
            folder, pattern = self.patterns[phase]
            if folder not in listings:
                try:
                    listings[folder] = os.listdir(folder)
                except FileNotFoundError:
                    listings[folder] = []
            if any(pattern.match(name) for name in listings[folder]):
                self.seen[phase] = self.cpu()

    def wait_for(self, phase: str) -> str | None:
        """Wait until ``phase`` or a later one has started; which one (None when the command ended first)."""
        later = list(PHASES[self.command])[list(PHASES[self.command]).index(phase):]
        while self.proc.poll() is None:
            self.look(later)
            for p in later:
                if p in self.seen:
                    return p
            time.sleep(POLL)
        return None

    def spend(self, seconds: float, since: float) -> None:
        """Wait until the command has used ``seconds`` of CPU time after its reading ``since`` (or has ended)."""
        while self.proc.poll() is None and self.cpu() - since < seconds:
            time.sleep(POLL)

    def finish(self, watch: bool = False) -> tuple[int, str]:
        """Wait for the end (``watch``: noting the phases on the way); the exit code and stderr."""
        while watch and self.proc.poll() is None:
            self.look(list(PHASES[self.command]))
            time.sleep(POLL)
        return self.proc.wait(), self.log.read_text()


def timeline(command: str, w: Path, log: Path) -> dict[str, float]:
    """Run ``command`` to its end: the CPU seconds of its start-up ('start'), of each phase it went through and
    of the whole ('any')."""
    run = Command(command, w, log)
    code, err = run.finish(watch=True)
    assert code == 0, err
    total = children_cpu() - run.cpu_before
    times = sorted(run.seen.items(), key=lambda kv: kv[1])
    ends = [t for _, t in times[1:]] + [total]
    return {"any": total, "start": times[0][1] if times else total,
            **{phase: end - t for (phase, t), end in zip(times, ends)}}


def comparable(path: Path) -> bytes:
    """A file's bytes; for stage records, whose figures include the stage's seconds, their content without
    the timings."""
    if path.name != STAGE_META:
        return path.read_bytes()
    return json.dumps(split_timings(json.loads(path.read_text()))[0], sort_keys=True).encode()


def outputs(w: Path) -> dict[str, str]:
    """sha256 of every file below ``w`` (relative names) but the lock files and the wall-clock timings."""
    return {str(p.relative_to(w)): hashlib.sha256(comparable(p)).hexdigest() for p in sorted(w.rglob("*"))
            if p.is_file() and p.name not in (LOCK_NAME, TIMINGS)}


@pytest.mark.slow
def test_a_pipeline_killed_at_20_random_moments_resumes_to_the_uninterrupted_result(tmp_path):
    w = tmp_path / "w"
    w.mkdir()
    (w / "c.toml").write_text(CONFIG)
    start = time.perf_counter()
    durations = {c: timeline(c, w, tmp_path / "ref.log") for c in PIPELINE}
    print(f"uninterrupted run {time.perf_counter() - start:.1f} s, CPU seconds:", durations)
    (tmp_path / "w").rename(tmp_path / "ref")  # the kills run in the same folder: the same absolute paths
    expected = outputs(tmp_path / "ref")
    w.mkdir()
    (w / "c.toml").write_text(CONFIG)

    rng = np.random.default_rng(20261201)
    complete = dict.fromkeys(PIPELINE, False)
    hit: list[tuple[str, str, str, int]] = []
    for command, phase in TARGETS:
        for upstream in PIPELINE[:PIPELINE.index(command) + (phase == "overwrite")]:
            if not complete[upstream]:
                code, err = Command(upstream, w, tmp_path / "resume.log").finish()
                assert code == 0, err
                complete[upstream] = True
        for attempt in range(ATTEMPTS):
            sig = SIGNALS[len(hit) % len(SIGNALS)]
            aim = "write" if phase == "overwrite" else phase
            delay = float(rng.uniform(0.0, durations[command].get(aim, 0.0) / 4 ** attempt))
            run = Command(command, w, tmp_path / "kill.log")
            reached = run.wait_for(aim) if aim in PHASES[command] else aim
            if reached == aim and aim != "write":  # within the phase; a later one (this one cached): at once
                run.spend(delay, since=run.seen.get(aim, 0.0))
            if run.proc.poll() is None:
                run.proc.send_signal(sig)
            code, err = run.finish()
            if code == 0:  # ended before the signal: the phase was cached or too short to be seen
                complete[command] = True
                if aim in STAGE_FOLDERS:  # its record lost, the stage is computed again
                    (w / STAGE_FOLDERS[aim] / STAGE_META).unlink()
                continue
            complete[command] = False
            # 130: pgc's interrupt path; -SIGINT: the interpreter's own (the signal came before pgc's handler)
            assert code in (130, -signal.SIGINT, -sig), (command, phase, sig, code, err)
            assert "Traceback" not in err or code == -signal.SIGINT, err
            assert code != 130 or "interrupted; completed stages are kept" in err, err
            for folder in ("asset", "run"):
                assert not is_locked(w / folder), f"{folder} still locked after {command} was killed"
            hit.append((command, phase, sig.name, code))
            break
        else:
            pytest.fail(f"{command} ended {ATTEMPTS} times before its phase '{phase}' could be interrupted")
    assert len(hit) == len(TARGETS)
    for command in PIPELINE:  # the last resume
        if not complete[command]:
            code, err = Command(command, w, tmp_path / "final.log").finish()
            assert code == 0, err
    print(f"{time.perf_counter() - start:.1f} s in all:", hit)

    leftovers = [str(p) for p in w.rglob(".*") if p.name != LOCK_NAME]
    assert not leftovers, f"orphan temporary files or folders: {leftovers}"
    assert not is_locked(w / "asset") and not is_locked(w / "run")
    got = outputs(w)
    assert got.keys() == expected.keys()
    assert [name for name in got if got[name] != expected[name]] == [], hit


def test_a_rewrite_removes_the_temporary_files_of_killed_writes_only(tmp_path):
    """An atomic write removes the temporary files that earlier writes of the same target left when killed
    (their process is gone), not those of a live writer nor those of other targets."""
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    assert not process_alive(gone.pid)
    dead = tmp_path / f".a.{gone.pid}.x1y2z3.tmp.npz"
    live = tmp_path / f".a.{os.getpid()}.q9w8e7.tmp.npz"
    other = tmp_path / f".a.b.{gone.pid}.r5t6y7.tmp.npz"
    for p in (dead, live, other):
        p.write_bytes(b"half")
    with atomic_path(tmp_path / "a.npz") as tmp:
        tmp.write_bytes(b"whole")
    assert (tmp_path / "a.npz").read_bytes() == b"whole"
    assert not dead.exists() and live.exists() and other.exists()
