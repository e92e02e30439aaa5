"""The thread-count chooser of pgc.cores: it runs the call on the count its own timings say is faster, and keeps
re-timing the others so the choice follows the load."""

from __future__ import annotations

import pytest

from pgc.cores import ThreadChooser


class FakeMachine:
    """A clock and a call whose duration per thread count is set by the test."""

    def __init__(self, seconds: dict[int, float]) -> None:
        self.seconds, self.now, self.log = dict(seconds), 0.0, []

    def clock(self) -> float:
        return self.now

    def call(self, threads: int) -> int:
        self.now += self.seconds[threads]
        self.log.append(threads)
        return threads * 10


def test_warm_up_then_each_count_once_then_the_faster():
    m = FakeMachine({2: 0.2, 1: 0.3})
    chooser = ThreadChooser([2, 1], probe_every=5, clock=m.clock)
    outs = [chooser.run(m.call) for _ in range(8)]
    assert m.log[:3] == [2, 2, 1]           # warm-up (untimed), then each count timed once
    assert m.log[3:8] == [2, 2, 2, 2, 1]    # the faster count; call 7 (5 after the last timing) probes 1
    assert outs[2] == 10 and chooser.choice == 2


def test_the_choice_follows_the_load_through_probes():
    m = FakeMachine({2: 0.2, 1: 0.3})
    chooser = ThreadChooser([2, 1], probe_every=4, clock=m.clock)
    for _ in range(4):
        chooser.run(m.call)
    assert chooser.choice == 2
    m.seconds[2] = 0.9                      # another process starts: two threads stall at every barrier
    for _ in range(3):
        chooser.run(m.call)
    assert m.log[-3:] == [2, 1, 2]          # slow once, then 1 thread; the probe finds 2 still slow
    assert chooser.choice == 1
    m.seconds[2] = 0.2                      # the machine is idle again
    for _ in range(5):
        chooser.run(m.call)
    assert chooser.choice == 2 and m.log[-2:] == [2, 2]


def test_one_candidate_or_one_core_never_probes(monkeypatch):
    m = FakeMachine({1: 0.1})
    chooser = ThreadChooser([1, 1], clock=m.clock)
    for _ in range(30):
        chooser.run(m.call)
    assert set(m.log) == {1} and chooser.candidates == [1]
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert ThreadChooser.for_cores().candidates == [1]
    with pytest.raises(ValueError):
        ThreadChooser([])


OPENBLAS_THREADS = """
import pgc, ctypes, pathlib, numpy
lib = next((pathlib.Path(numpy.__file__).parent.parent / "numpy.libs").glob("libscipy_openblas64_*.so"))
print(ctypes.CDLL(str(lib)).scipy_openblas_get_num_threads64_())
"""
"""Prints the thread count of numpy's OpenBLAS (the pinned numpy wheel's own library) after ``import pgc``."""


@pytest.mark.parametrize("given, expected", [(None, 1), ("2", 2)])
def test_import_pgc_holds_numpy_s_blas_to_one_thread_unless_one_is_given(given, expected):
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    out = subprocess.run([sys.executable, "-c", OPENBLAS_THREADS], env=env, capture_output=True, text=True,
                         check=True).stdout
    assert int(out) == expected
