"""`pgc info`: what an asset or a run holds, as text and JSON, from the files alone."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgc.cli import main
from test_export import FPS, FRAMES, run_dir  # noqa: F401  (the fixture)


def test_info_of_an_asset_lists_meshes_gaussians_material_light_provenance(run_dir, tmp_path, capsys):
    _, asset = run_dir
    assert main(["info", str(tmp_path / "asset"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["garment"] == {"vertices": 16, "faces": 18, "uv": 36}
    assert info["body"] == {"vertices": 4, "faces": 2}
    assert info["gaussians"] == {"count": 18, "sh_degree": 1}
    assert info["material"]["brdf"] == "pgc-sheen" and info["material"]["base_color"] == [8, 8]
    np.testing.assert_allclose(info["material"]["params"]["sheen_color"], [0.6, 0.5, 0.1])
    np.testing.assert_allclose(info["light"]["radiance"], [1.0, 0.9, 0.8])
    assert info["figures"] == {"mesh": {"vertices": 4}} and info["timings"]["seconds"] == {"mesh": 1.5}
    assert info["provenance"]["source"] == {"capture": "/nowhere/capture"}
    assert "numpy" in info["provenance"]["versions"] and "gaussians" in info["provenance"]["files"]
    assert main(["info", str(tmp_path / "asset")]) == 0
    text = capsys.readouterr().out
    for part in ("16 vertices, 18 faces, 36 UVs", "gaussians: 18, SH degree 1", "brdf pgc-sheen: roughness=0.7",
                 "sheen_color=[0.6, 0.5, 0.1]", "stage seconds: mesh 1.5", "source: capture /nowhere/capture",
                 "written with python"):
        assert part in text, part


def test_info_of_a_run_adds_the_motion(run_dir, capsys):
    run, _ = run_dir
    assert main(["info", str(run), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["motion"], info["frames"], info["fps"], info["simulator"]) == ("wave", FRAMES, FPS, "test")
    assert "render" not in info and info["asset"]["gaussians"]["count"] == 18
    assert main(["info", str(run)]) == 0
    text = capsys.readouterr().out
    assert f"motion wave: {FRAMES} frames at {FPS} fps" in text and "not rendered yet (pgc render RUN)" in text


def test_info_errors_name_the_folder_and_the_fix(tmp_path, capsys):
    assert main(["info", str(tmp_path / "gone")]) == 2
    assert "gone: no such folder" in capsys.readouterr().err
    (tmp_path / "run.json").write_text("{not json")
    assert main(["info", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "run.json" in err and "pgc animate" in err
    with pytest.raises(SystemExit):
        main(["info", "--help"])
    assert "examples:" in capsys.readouterr().out
