"""Static checks: ruff (pyflakes, import order, docstrings of every module of app/; configured in
pyproject.toml), no import cycle between the modules of app/, the layout of app/ (one folder per
stage of the data flow, imports only down the stages) and the size limits of modules and functions."""
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


def _module_name(path: pathlib.Path, root: pathlib.Path | None = None) -> str:
    parts = path.relative_to(root or ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def app_imports(root: pathlib.Path | None = None) -> list[tuple[str, str, int, str]]:
    """Every import of an app module by a module of app/, at module level or inside functions (a
    lazy import still ties the two modules together): ``(module, file, line, imported module)``,
    the imported name resolved to the module (or package) that defines it."""
    root = root or ROOT
    modules = {_module_name(p, root): p for p in (root / "app").rglob("*.py")}
    out: list[tuple[str, str, int, str]] = []
    seen: set[tuple[str, str, int, str]] = set()
    for mod, path in sorted(modules.items()):
        is_pkg = path.name == "__init__.py"
        rel = str(path.relative_to(root))
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
                hit = (mod, rel, node.lineno, n)
                if n and n != mod and not mod.startswith(n + ".") and hit not in seen:   # (a package's own
                    seen.add(hit)                                                      # __init__ is no cycle)
                    out.append(hit)
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the app modules it imports (:func:`app_imports`)."""
    graph: dict[str, set[str]] = {_module_name(p): set() for p in (ROOT / "app").rglob("*.py")}
    for mod, _, _, n in app_imports():
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


# ---- the layout of app/ ----------------------------------------------------------------------

#: The stages of app/, top to bottom, one folder each. A module may import modules of its own
#: stage and of the stages below it, never above (lazy imports inside functions included); the
#: stages of one row are peers. The scene is above the systems because ``Scene.system`` is the
#: union of the registered system types' schemas (app/systems/<type>/schema.py); the systems are
#: above loading because each type's ``path`` runs the contact toolbox of app/loading/.
STAGES: list[tuple[str, ...]] = [("cli",), ("study",), ("analyses", "io", "plot"), ("scene",), ("systems",),
                                 ("loading",), ("common",)]
#: Modules directly in app/, outside the stages: the package and the public API may import any
#: stage (and no stage imports them); linalg and version may be imported by any stage, so they
#: themselves import nothing of app/ but app/common/.
TOP_LEVEL = {"app": "api", "app.__main__": "api", "app.api": "api", "app.linalg": "shared", "app.version": "shared"}
#: Folders of app/ that hold data, not modules.
DATA_FOLDERS = {"scenes"}
#: Modules are split by topic, not by length: a module over MODULE_REVIEW_LINES lines or a function
#: (methods and nested functions included) over FUNCTION_REVIEW_LINES lines is allowed only with a
#: reason a reviewer accepted, listed in LONG_WITH_REASON under its path ("app/x/y.py") or its
#: function ("app/x/y.py:name").
MODULE_REVIEW_LINES = 500
FUNCTION_REVIEW_LINES = 80
LONG_WITH_REASON: dict[str, str] = {
    "app/io/result.py": "the one description of results.json: every record's model with its queries, from which "
                        "the writer, the reader and the JSON Schema come; split, the format would be in pieces",
}


def _rank(module: str) -> int | None:
    """Row of ``module``'s stage in :data:`STAGES` (0 is the top), None outside the stages."""
    if module in TOP_LEVEL:
        return None
    parts = module.split(".")
    for i, row in enumerate(STAGES):
        if len(parts) > 1 and parts[1] in row:
            return i
    return None


def upward_imports(root: pathlib.Path | None = None) -> list[str]:
    """Imports that break :data:`STAGES`: one line each, naming the file, line, both modules."""
    found = []
    names = " -> ".join("(" + ", ".join(r) + ")" if len(r) > 1 else r[0] for r in STAGES)
    for mod, rel, line, target in app_imports(root):
        kind, tkind = TOP_LEVEL.get(mod), TOP_LEVEL.get(target)
        if kind == "api":
            continue
        if tkind == "api":
            found.append(f"{rel}:{line}: {mod} imports {target}, which may import every stage (no stage imports it)")
        elif tkind == "shared":
            continue
        elif kind == "shared":
            if _rank(target) != len(STAGES) - 1:
                found.append(f"{rel}:{line}: {mod} (importable by every stage) imports {target}: only app.common may be")
        elif _rank(target) is not None and _rank(mod) is not None and _rank(target) < _rank(mod):
            found.append(f"{rel}:{line}: {mod} imports {target}: {target.split('.')[1]} is above "
                         f"{mod.split('.')[1]} in the stages {names}")
    return found


def layout_problems(root: pathlib.Path | None = None) -> list[str]:
    """Folders of app/ that are not a stage, and modules directly in app/ that are not listed."""
    root = root or ROOT
    stages = {s for row in STAGES for s in row}
    found = []
    for p in sorted((root / "app").iterdir()):
        if p.name.startswith((".", "__pycache__")):
            continue
        if p.is_dir() and not any(q.is_file() and "__pycache__" not in q.parts for q in p.rglob("*")):
            continue        # e.g. only the bytecode of a folder that was moved away
        if p.is_dir() and p.name in DATA_FOLDERS:
            found += [f"{q.relative_to(root)}: a module in the data folder app/{p.name}/" for q in p.rglob("*.py")]
        elif p.is_dir() and p.name not in stages:
            found.append(f"{p.relative_to(root)}/: not one of the stages ({', '.join(sorted(stages))})")
        elif p.is_file() and p.suffix == ".py" and _module_name(p, root) not in TOP_LEVEL:
            found.append(f"{p.relative_to(root)}: a module outside the stages (put it in one of the stage folders)")
    return found


def size_problems(root: pathlib.Path | None = None, reasons: dict[str, str] | None = None) -> list[str]:
    """Modules over :data:`MODULE_REVIEW_LINES` lines and functions over
    :data:`FUNCTION_REVIEW_LINES` without a reason in ``reasons`` (default
    :data:`LONG_WITH_REASON`), and reasons for code that is no longer long."""
    root = root or ROOT
    reasons = LONG_WITH_REASON if reasons is None else reasons
    found, long = [], set()
    for path in sorted((root / "app").rglob("*.py")):
        rel = str(path.relative_to(root))
        text = path.read_text(encoding="utf-8")
        n = len(text.splitlines())
        if n > MODULE_REVIEW_LINES:
            long.add(rel)
            if rel not in reasons:
                found.append(f"{rel}: {n} lines (over {MODULE_REVIEW_LINES}: split it by topic, or give the reason)")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > FUNCTION_REVIEW_LINES:
                    long.add(f"{rel}:{node.name}")
                    if f"{rel}:{node.name}" not in reasons:
                        found.append(f"{rel}:{node.lineno}: function {node.name} has {length} lines "
                                     f"(over {FUNCTION_REVIEW_LINES}: split it, or give the reason)")
    found += [f"{key}: listed as long, but no longer is" for key in sorted(set(reasons) - long)]
    return found


def test_layout_checks_see_what_they_forbid(tmp_path):
    """The checks name an upward import (lazy too), a stray folder, a loose module, a long
    function and a long module (on a small fake app/)."""
    app = tmp_path / "app"
    for d in ("common", "loading", "study", "cli", "misc"):
        (app / d).mkdir(parents=True)
        (app / d / "__init__.py").write_text("")
    (app / "__init__.py").write_text("")
    (app / "common" / "errors.py").write_text("def f():\n    from app.study.run import g\n    return g\n")
    (app / "loading" / "state.py").write_text("from app.common.errors import f\n" + "\n" * 500)
    (app / "study" / "run.py").write_text("from app.cli.main import x\n\n\ndef g():\n" + "    pass\n" * 80)
    (app / "cli" / "main.py").write_text("from app.study.run import g\nx = 1\n")
    (app / "helpers.py").write_text("")
    assert upward_imports(tmp_path) == [
        "app/common/errors.py:2: app.common.errors imports app.study.run: study is above common in the stages "
        "cli -> study -> (analyses, io, plot) -> scene -> systems -> loading -> common",
        "app/study/run.py:1: app.study.run imports app.cli.main: cli is above study in the stages "
        "cli -> study -> (analyses, io, plot) -> scene -> systems -> loading -> common"]
    assert [p.split(":")[0] for p in layout_problems(tmp_path)] == ["app/helpers.py", "app/misc/"]
    assert size_problems(tmp_path, {}) == [
        "app/loading/state.py: 501 lines (over 500: split it by topic, or give the reason)",
        "app/study/run.py:4: function g has 81 lines (over 80: split it, or give the reason)"]
    assert size_problems(tmp_path, {"app/loading/state.py": "one topic", "app/study/run.py:g": "a table",
                                    "app/cli/main.py": "was long"}) == [
        "app/cli/main.py: listed as long, but no longer is"]


def test_imports_run_down_the_stages():
    """cli -> study -> (analyses, io, plot) -> scene -> systems -> loading -> common: no module
    imports one of a stage above its own (:data:`STAGES`)."""
    found = upward_imports()
    assert not found, "imports against the stages:\n" + "\n".join(found)


def test_every_folder_of_app_is_a_stage():
    found = layout_problems()
    assert not found, "layout of app/:\n" + "\n".join(found)


def test_long_modules_and_functions_have_a_reason():
    found = size_problems()
    assert not found, "long code without a reason:\n" + "\n".join(found)


#: The trusted kernels of the proofs and what they may import of app/: a proof is what these
#: modules re-verify, so they never import the prover that produced it.
KERNELS = {"app.analyses.mceip_mu.kernel": ("app.analyses.mceip_mu.kernel", "app.linalg", "app.common"),
           "app.analyses.mceip_mu.quadratic.check": ("app.analyses.mceip_mu.kernel",
                                                     "app.analyses.mceip_mu.quadratic.proof", "app.linalg")}


def test_the_trusted_kernels_import_nothing_of_the_provers():
    found = []
    for mod, rel, line, target in app_imports():
        for kernel, allowed in KERNELS.items():
            if (mod == kernel or mod.startswith(kernel + ".")) and not any(
                    target == a or target.startswith(a + ".") for a in allowed):
                found.append(f"{rel}:{line}: {mod} imports {target}")
    assert not found, "the trusted kernels import beyond themselves:\n" + "\n".join(found)
