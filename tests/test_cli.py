"""The `pgc` command line: every command has help; errors are one line on stderr with exit code 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

from pgc.cli import COMMANDS, build_parser, main


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize("command", COMMANDS)
def test_each_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args([command, "--help"])
    assert exc.value.code == 0
    assert len(capsys.readouterr().out.strip()) > 40


def test_no_command_prints_help(capsys):
    assert main([]) == 0
    assert "usage: pgc" in capsys.readouterr().out


def test_errors_are_one_clear_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pgc.cli", "config", "validate", str(tmp_path / "none.toml")],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert out.stderr.strip() == f"pgc config: error: {tmp_path / 'none.toml'}: config file not found"


def test_console_script_installed():
    import shutil
    from pathlib import Path

    exe = Path(sys.executable).with_name("pgc")
    script = str(exe) if exe.exists() else shutil.which("pgc")
    assert script, "the 'pgc' console script is not installed (run scripts/setup.sh)"
    out = subprocess.run([script, "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("pgc ")


def test_plugins_role_filter(capsys):
    assert main(["plugins", "--role", "filter"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("filter:\n") and "box" in out and "metric:" not in out
    with pytest.raises(SystemExit) as exc:
        main(["plugins", "--role", "filtre"])
    assert exc.value.code == 2
    assert "invalid choice: 'filtre'" in capsys.readouterr().err
