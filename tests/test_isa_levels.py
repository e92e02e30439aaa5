"""The agreement tests hold on any x86 instruction set, not only on the machine's own.

torch (ATen's kernels, ``ATEN_CPU_CAPABILITY``), oneDNN's convolutions (``ONEDNN_MAX_CPU_ISA``) and XLA
(``--xla_cpu_max_isa``) choose their SIMD kernels at run time from the CPU: on another CPU the same program
rounds differently (vector widths change the order of reductions; transcendental functions have one
implementation per width). Every test marked ``agreement`` (backends against each other, kernels against the
float64 reference, simulators against each other, the fit loop's first step) is run again here in a subprocess
with each library held one level below the machine's own, so the suite that CI runs covers a second
instruction set on every machine. The one that is also ``slow`` (a whole fit on three backends, 70 s) runs at
the machine's level only; its spread under the forced levels is measured in docs/robustness.md. The fused
splat kernel and the native XPBD kernel are compiled for the host by the project (their own flags,
docs/robustness.md); Dr.Jit compiles for the host and has no switch.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def cpu_flags() -> set[str]:
    """The CPU's feature flags as Linux reports them (empty where /proc/cpuinfo does not exist)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((ln for ln in text.splitlines() if ln.startswith("flags")), "")
    return set(line.partition(":")[2].split())


def forced_levels(flags: set[str]) -> dict[str, str]:
    """The environment that holds torch, oneDNN and XLA one level below what ``flags`` support: AVX2 on an
    AVX-512 CPU; on an AVX2 CPU torch's portable kernels, oneDNN's SSE4.1 and XLA's SSE4.2."""
    if "avx512f" in flags:
        return {"ATEN_CPU_CAPABILITY": "avx2", "ONEDNN_MAX_CPU_ISA": "AVX2", "XLA_FLAGS": "--xla_cpu_max_isa=AVX2"}
    return {"ATEN_CPU_CAPABILITY": "default", "ONEDNN_MAX_CPU_ISA": "SSE41", "XLA_FLAGS": "--xla_cpu_max_isa=SSE4_2"}


def agreement_files() -> list[str]:
    """The test files that mark tests ``agreement`` (their source names ``mark.agreement``), relative to the
    repository root: the forced-level run collects these only, not the whole suite (13 CPU s of imports and
    collection for 44 of 1778 tests). :func:`test_agreement_files_hold_every_agreement_test` checks the scan
    against what pytest collected."""
    return sorted(str(p.relative_to(ROOT)) for p in (ROOT / "tests").glob("test_*.py")
                  if p.name != Path(__file__).name and "mark.agreement" in p.read_text())


def test_agreement_files_hold_every_agreement_test(request):
    """Every ``agreement`` test this session collected (the whole suite under ``make test``) is in a file that
    :func:`agreement_files` names."""
    files = agreement_files()
    assert "tests/test_splat_torch_vs_jax.py" in files and "tests/test_isa_levels.py" not in files
    collected = {str(item.path.relative_to(ROOT)) for item in request.session.items
                 if item.get_closest_marker("agreement")}
    assert collected <= set(files), sorted(collected - set(files))


def test_forced_levels_are_below_the_cpu_s_own():
    assert forced_levels({"avx512f", "avx2", "fma"})["ATEN_CPU_CAPABILITY"] == "avx2"
    assert forced_levels({"avx2", "fma"})["ATEN_CPU_CAPABILITY"] == "default"
    assert "AVX2" in forced_levels({"avx512f"})["XLA_FLAGS"] and "SSE4_2" in forced_levels(set())["XLA_FLAGS"]


@pytest.mark.slow
def test_the_agreement_tests_pass_one_instruction_set_below_the_machine_s_own():
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    forced = forced_levels(cpu_flags())
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "PYTEST_ADDOPTS")} | forced
    probe = subprocess.run([sys.executable, "-c", "import torch; print(torch.backends.cpu.get_cpu_capability())"],
                           env=env, capture_output=True, text=True, timeout=120)
    assert probe.returncode == 0 and probe.stdout.strip() == forced["ATEN_CPU_CAPABILITY"].upper(), probe
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-m", "agreement and not slow", "-p",
                          "no:cacheprovider", "-o", "addopts=", *agreement_files()], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=1200)
    tail = "\n".join(run.stdout.splitlines()[-30:])
    assert run.returncode == 0, f"agreement tests under {forced}:\n{tail}\n{run.stderr[-2000:]}"
    assert " passed" in tail and " failed" not in tail, tail
