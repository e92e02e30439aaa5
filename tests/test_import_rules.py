"""Import direction and import cycles, read from the source with ``ast`` (every import statement, at module
level or inside functions; nothing is imported).

Layers (docs/architecture.md): the core (everything in ``pgc/`` except the pipeline and command layers)
<- the pipeline (``pgc.pipeline``, ``pgc.bench``, ``pgc.sweep``) and the commands (``pgc.commands``,
``pgc.cli``). Rules:
- nothing in ``pgc/`` imports a ``pgc_*`` package (implementations are reached through the registry);
- a backend or plugin (``backends/pgc_*``, ``plugins/pgc_*``) imports no upper layer and no other
  ``pgc_*`` package (its own is fine);
- the core imports no upper layer (``pgc.testing`` is a kit for tests and may use anything of ``pgc``);
- the synthetic-data generator (``pgc.synth``) is a client of the core: no core module, backend or plugin
  imports it (what a scene renderer receives lives with its role, ``pgc.roles.scene_renderer``).
Cycles: the graph of imports between the modules of ``pgc``, the backends and the plugins (module and
function level; imports under ``if TYPE_CHECKING:`` do not run and are left out) has no cycle.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UPPER = ("pgc.pipeline", "pgc.commands", "pgc.cli", "pgc.bench", "pgc.sweep")
"""The pipeline and command layers."""
GENERATOR = ("pgc.synth",)
"""The synthetic-data generator: it uses the core; only the upper layers and the testing kit use it."""
NOT_CORE = UPPER + ("pgc.testing",)


@dataclass(frozen=True)
class Import:
    module: str
    """The importing module."""
    target: str
    """The imported module (the deepest name that is a module of the tree, else the name as written)."""
    line: int
    path: Path
    type_only: bool


def _within(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def source_modules(root: Path) -> dict[str, Path]:
    """Module name -> file for ``pgc/`` and every ``backends/pgc_*`` and ``plugins/pgc_*`` package."""
    tops = [root / "pgc"] + sorted(p for d in ("backends", "plugins") for p in (root / d).glob("pgc_*") if p.is_dir())
    out: dict[str, Path] = {}
    for top in tops:
        for path in sorted(top.rglob("*.py")):
            parts = list(path.relative_to(top.parent).with_suffix("").parts)
            if "__pycache__" in parts:
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of import nodes inside ``if TYPE_CHECKING:`` blocks."""
    ids: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            name = test.id if isinstance(test, ast.Name) else test.attr if isinstance(test, ast.Attribute) else ""
            if name == "TYPE_CHECKING":
                ids.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return ids


def imports(root: Path) -> list[Import]:
    """Every import statement of the tree, resolved to module names."""
    modules = source_modules(root)
    out: list[Import] = []
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        type_only = _type_checking_nodes(tree)
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            else:
                continue
            for name in dict.fromkeys(names):
                out.append(Import(module, name, node.lineno, path, id(node) in type_only))
    return out


def violations(root: Path) -> list[str]:
    """One line per import that breaks a layer rule."""
    found = []
    for imp in imports(root):
        top, target_top = imp.module.split(".")[0], imp.target.split(".")[0]
        where = f"{imp.path.relative_to(root)}:{imp.line}: {imp.module} imports {imp.target}"
        if top == "pgc":
            if target_top.startswith("pgc_"):
                found.append(f"{where} (the core package reaches implementations through the registry)")
            elif _within(imp.target, UPPER) and not _within(imp.module, NOT_CORE):
                found.append(f"{where} (the core imports no pipeline or command module)")
            elif _within(imp.target, GENERATOR) and not _within(imp.module, NOT_CORE + GENERATOR):
                found.append(f"{where} (the core never imports the generator)")
        elif top.startswith("pgc_"):
            if _within(imp.target, UPPER + GENERATOR):
                found.append(f"{where} (a backend or plugin imports only the core)")
            elif target_top.startswith("pgc_") and target_top != top:
                found.append(f"{where} (backends and plugins never import each other)")
    return found


def cycles(root: Path) -> list[list[str]]:
    """One cycle (a list of modules, the first repeated at the end) per strongly connected component of the
    import graph with more than one module."""
    modules = source_modules(root)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for imp in imports(root):
        if not imp.type_only and imp.target in modules and imp.target != imp.module:
            graph[imp.module].add(imp.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def connect(v: str) -> None:  # Tarjan, iterative over the edges of each node
        work = [(v, iter(sorted(graph[v])))]
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        while work:
            node, edges = work[-1]
            for w in edges:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        components.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return [_cycle_in(graph, comp) for comp in components]


def _cycle_in(graph: dict[str, set[str]], component: list[str]) -> list[str]:
    """A shortest cycle through the first module of ``component`` (breadth-first inside the component)."""
    members, start = set(component), component[0]
    parent: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(parent[path[-1]])
                    return [start] + path[::-1][1:] + [start] if len(path) > 1 else [start, v, start]
                if w not in parent:
                    parent[w] = v
                    nxt.append(w)
        frontier = nxt
    raise AssertionError(f"no cycle through {start} in {component}")


# ---------------------------------------------------------------------------------------------- the tests


def _write(root: Path, rel: str, text: str) -> None:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_checker_catches_planted_violations_and_cycles(tmp_path):
    _write(tmp_path, "pgc/__init__.py", "")
    _write(tmp_path, "pgc/pipeline/__init__.py", "")
    _write(tmp_path, "pgc/pipeline/run.py", "from pgc.geometry import good\n")
    _write(tmp_path, "pgc/geometry/__init__.py", "")
    _write(tmp_path, "pgc/geometry/good.py", "import numpy\nfrom . import other\n")
    _write(tmp_path, "pgc/geometry/other.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                              "    from pgc.geometry import good\n")
    _write(tmp_path, "pgc/geometry/bad.py", "def f():\n    import pgc_torch.fit\n    from ..pipeline import run\n")
    _write(tmp_path, "pgc/testing/__init__.py", "from pgc.pipeline import run\n")
    _write(tmp_path, "backends/pgc_torch/__init__.py", "")
    _write(tmp_path, "backends/pgc_torch/fit.py", "from pgc_torch import renderer\nfrom pgc.commands import x\n")
    _write(tmp_path, "backends/pgc_torch/renderer.py", "def g():\n    from .fit import h\n")
    _write(tmp_path, "plugins/pgc_colmap/__init__.py", "")
    _write(tmp_path, "plugins/pgc_colmap/calibrate.py", "import pgc_torch.fit\nfrom pgc.types import Camera\n")
    found = violations(tmp_path)
    assert len(found) == 4, found
    assert any("pgc.geometry.bad imports pgc_torch.fit" in v and "registry" in v for v in found)
    assert any("pgc.geometry.bad imports pgc.pipeline.run" in v for v in found)  # relative, function level
    assert any("pgc_torch.fit imports pgc.commands" in v for v in found)
    assert any("pgc_colmap.calibrate imports pgc_torch.fit" in v for v in found)
    assert cycles(tmp_path) == [["pgc_torch.fit", "pgc_torch.renderer", "pgc_torch.fit"]]  # not good<->other


def test_the_checker_keeps_the_generator_out_of_the_core_and_backends(tmp_path):
    _write(tmp_path, "pgc/__init__.py", "")
    _write(tmp_path, "pgc/synth/__init__.py", "")
    _write(tmp_path, "pgc/synth/render.py", "from pgc.roles import scene_renderer\n")
    _write(tmp_path, "pgc/synth/generate.py", "from pgc.synth import render\n")  # inside the generator: fine
    _write(tmp_path, "pgc/pipeline/__init__.py", "from pgc.synth import render\n")  # an upper layer: fine
    _write(tmp_path, "pgc/testing/__init__.py", "from pgc.synth import render\n")  # the testing kit: fine
    _write(tmp_path, "pgc/roles/__init__.py", "")
    _write(tmp_path, "pgc/roles/scene_renderer.py", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                                    "    from pgc.synth.render import x\n")
    _write(tmp_path, "pgc/albedo/dataset.py", "def f():\n    from pgc.synth import generate\n")
    _write(tmp_path, "backends/pgc_mitsuba/__init__.py", "")
    _write(tmp_path, "backends/pgc_mitsuba/synth_scene.py", "from pgc.synth.render import SceneGeometry\n")
    found = violations(tmp_path)
    assert len(found) == 3, found
    assert any("pgc.roles.scene_renderer imports pgc.synth.render" in v and "generator" in v for v in found)
    assert any("pgc.albedo.dataset imports pgc.synth.generate" in v for v in found)  # function level
    assert any("pgc_mitsuba.synth_scene imports pgc.synth.render" in v for v in found)


def test_the_tree_is_parsed():
    modules = source_modules(ROOT)
    assert {"pgc.registry", "pgc.synth.render", "pgc_mitsuba.synth_scene", "pgc_colmap.calibrate"} <= set(modules)
    targets = {(i.module, i.target) for i in imports(ROOT)}
    assert ("pgc.synth.render", "pgc.errors") in targets  # a function-level import


def test_import_directions():
    found = violations(ROOT)
    assert not found, f"{len(found)} import(s) break the layer rules:\n" + "\n".join(found)


def test_no_import_cycles():
    found = cycles(ROOT)
    assert not found, f"{len(found)} import cycle(s):\n" + "\n".join(" -> ".join(c) for c in found)
