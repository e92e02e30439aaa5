"""`import pgc` and building the CLI (every subcommand's parser, `pgc sweep` included) must not import the heavy
array/geometry libraries, nor Dask."""

import subprocess
import sys

HEAVY = ("torch", "jax", "mitsuba", "drjit", "open3d", "pycolmap", "pymeshlab", "onnxruntime", "cv2", "dask", "distributed")


def test_import_pgc_and_cli_stay_light():
    code = ("import sys, pgc, pgc.cli, pgc.config, pgc.registry, pgc.types; pgc.cli.build_parser(); "
            "from pgc.registry import Registry; r = Registry.discover(); "
            "from pgc import config; config.load(registry=r, require_available=False); "
            f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"heavy modules imported: {out.stdout.strip()}"
