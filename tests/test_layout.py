"""The layout says what it holds: the segmentation ids (background 0, body 1, garment 2) are defined once, in
``pgc.types``; read from the source with ``ast`` (nothing is imported)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LABEL_NAMES = {"background", "body", "garment"}


def _ints(node: ast.AST) -> bool:
    """Whether ``node`` is an int literal or a tuple of them."""
    if isinstance(node, ast.Tuple):
        return bool(node.elts) and all(_ints(e) for e in node.elts)
    return isinstance(node, ast.Constant) and type(node.value) is int


def label_definitions(root: Path) -> list[str]:
    """``path:line: what`` for every definition of segmentation ids in ``pgc/``, the backends and the plugins:
    an int literal assigned to a name containing ``LABEL``, or a dict literal from int literals to the label
    names."""
    files = sorted((root / "pgc").rglob("*.py")) + sorted(
        p for d in ("backends", "plugins") for p in (root / d).glob("pgc_*/**/*.py"))
    found = []
    for path in files:
        where = path.relative_to(root)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None and _ints(node.value):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names = [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name) and "LABEL" in n.id]
                found += [f"{where}:{node.lineno}: {n}" for n in names]
            elif isinstance(node, ast.Dict) and node.keys and all(k is not None and _ints(k) for k in node.keys) \
                    and any(isinstance(v, ast.Constant) and v.value in LABEL_NAMES for v in node.values):
                found.append(f"{where}:{node.lineno}: {{id: name}}")
    return found


def test_the_scan_finds_planted_definitions(tmp_path):
    (tmp_path / "pgc").mkdir()
    (tmp_path / "pgc" / "types.py").write_text("BODY_LABEL = 1\nNAMES = {BODY_LABEL: 'body'}\n")
    (tmp_path / "backends" / "pgc_x").mkdir(parents=True)
    (tmp_path / "backends" / "pgc_x" / "scene.py").write_text(
        "LABEL_BODY, LABEL_GARMENT = 1, 2\nLABEL_GROUP = 'g'\ndef f():\n    x: dict = {0: 'background'}\n")
    assert label_definitions(tmp_path) == ["pgc/types.py:1: BODY_LABEL", "backends/pgc_x/scene.py:1: LABEL_BODY",
                                           "backends/pgc_x/scene.py:1: LABEL_GARMENT",
                                           "backends/pgc_x/scene.py:4: {id: name}"]


def test_segmentation_ids_are_defined_once_in_pgc_types():
    found = label_definitions(ROOT)
    assert sorted(d.rsplit(" ", 1)[1] for d in found if d.startswith("pgc/types.py:")) == \
        ["BACKGROUND_LABEL", "BODY_LABEL", "GARMENT_LABEL"]
    elsewhere = [d for d in found if not d.startswith("pgc/types.py:")]
    assert not elsewhere, "segmentation ids are defined in pgc.types only; import them:\n" + "\n".join(elsewhere)
