"""Static checks: ruff (pyflakes, import order, docstrings of the public API; configured in
pyproject.toml) and no import cycle between the modules of app/."""
from __future__ import annotations

import ast
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _ruff() -> str | None:
    exe = pathlib.Path(sys.executable).parent / "ruff"
    return str(exe) if exe.exists() else shutil.which("ruff")


def test_ruff_passes():
    ruff = _ruff()
    if ruff is None:   # installed by scripts/setup.sh (the test extra); a bare checkout may lack it
        pytest.skip("ruff is not installed (run scripts/setup.sh)")
    proc = subprocess.run([ruff, "check", "--no-cache", "--output-format", "concise", "."], cwd=ROOT,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Module -> the app modules it imports, at module level or inside functions (a lazy import
    still ties the two modules together)."""
    modules = {_module_name(p): p for p in (ROOT / "app").rglob("*.py")}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for mod, path in modules.items():
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    pkg = pkg[:len(pkg) - node.level + 1]
                    base = ".".join(pkg + ([base] if base else []))
                names = [base] + [f"{base}.{a.name}" for a in node.names]
            for n in names:
                while n and n not in modules:
                    n = n.rpartition(".")[0]
                if n and n != mod and not mod.startswith(n + "."):   # a package's own __init__ is not a cycle
                    graph[mod].add(n)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_detector_sees_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles_in_app():
    graph = import_graph()
    assert "app.study.run" in graph and "app.scene.schema" in graph["app.study.run"]
    found = cycles(graph)
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def system_type_checks() -> list[str]:
    """Places in app/ outside app/systems/ that branch on the system type: comparisons with a
    ``.type`` attribute or a registered type name, ``isinstance``/``issubclass`` against a system
    schema, dictionaries keyed by type names."""
    from app.systems import SYSTEM_TYPES
    names = set(SYSTEM_TYPES)
    schemas = {t.schema.__name__ for t in SYSTEM_TYPES.values()}
    found = []
    for path in sorted((ROOT / "app").rglob("*.py")):
        rel = path.relative_to(ROOT)
        if rel.parts[:2] == ("app", "systems"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            hit = False
            if isinstance(node, ast.Compare):
                for side in [node.left, *node.comparators]:
                    if isinstance(side, ast.Attribute) and side.attr == "type":
                        hit = True
                    if isinstance(side, ast.Constant) and side.value in names:
                        hit = True
                    if (isinstance(side, ast.Call) and isinstance(side.func, ast.Attribute) and side.func.attr == "get"
                            and side.args and isinstance(side.args[0], ast.Constant) and side.args[0].value == "type"):
                        hit = True
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("isinstance",
                                                                                                    "issubclass"):
                hit = any(isinstance(n, ast.Name) and n.id in schemas for a in node.args[1:] for n in ast.walk(a))
            elif isinstance(node, ast.Dict):
                hit = any(isinstance(k, ast.Constant) and k.value in names for k in node.keys)
            if hit:
                found.append(f"{rel}:{node.lineno}")
    return found


def test_system_type_checks_are_found(tmp_path, monkeypatch):
    """The detector sees the patterns it is meant to forbid (checked on a copy of app/)."""
    import shutil as sh
    fake = tmp_path / "app"
    sh.copytree(ROOT / "app" / "systems", fake / "systems")
    (fake / "x.py").write_text("def f(scene, cfg):\n    if scene.system.type == 'gmsh':\n        pass\n"
                               "    if isinstance(cfg, Block):\n        pass\n    return {'block': 1}\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert system_type_checks() == ["app/x.py:2", "app/x.py:4", "app/x.py:6"]


def test_nothing_outside_the_registry_tests_the_system_type():
    """Type-specific behaviour is asked of the registry (app/systems/), never branched on."""
    found = system_type_checks()
    assert not found, "system type tested outside app/systems/: " + ", ".join(found)


def test_no_private_names_imported_across_modules():
    """``from app.x import _name`` ties a module to another's internals: shared helpers are public."""
    found = []
    for path in sorted((ROOT / "app").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("app"):
                found += [f"{path.relative_to(ROOT)}:{node.lineno} {node.module}.{a.name}" for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
    assert not found, "private names imported: " + ", ".join(found)
