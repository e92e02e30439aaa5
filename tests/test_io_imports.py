"""Importing the file-format modules stays light: codecs and mesh libraries load only when used."""

import subprocess
import sys

MODULES = ("pgc.io.atomic", "pgc.io.images", "pgc.io.capture", "pgc.io.colmap", "pgc.io.gaussians_ply",
           "pgc.io.mesh", "pgc.io.asset", "pgc.io.motion", "pgc.testing.conformance")
HEAVY = ("torch", "jax", "mitsuba", "drjit", "open3d", "pycolmap", "cv2", "trimesh", "OpenEXR", "PIL")


def test_io_modules_import_no_heavy_library():
    code = (f"import sys, importlib; [importlib.import_module(m) for m in {MODULES!r}]; "
            f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"heavy modules imported: {out.stdout.strip()}"
