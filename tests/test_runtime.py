"""The process-wide patches of the runtime are made behind one door, app/common/runtime.py: an
AST scan of app/ finds any made elsewhere; each patch checks the library version it relies on and,
on another one, says so in one DEBUG line instead of failing; the Python API installs none of the
command line's signal handlers, hooks or environment variables."""
from __future__ import annotations

import ast
import logging
import os
import pathlib
import signal
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOOR = "app/common/runtime.py"

#: process-wide changes app/ makes outside the door on purpose: (file, what) -> why
EXCEPTIONS: dict[tuple[str, str], str] = {
    ("app/plot/worker.py", "signal.signal"):
        "the drawing process is an interpreter of its own (python -m app.plot.worker): its entry point "
        "ignores SIGINT, as the run that started it ends it by closing its standard input",
    ("app/common/logs.py", ".addFilter"):
        "the command line's own stderr handler, not a library's logger (ordinary logging set-up)",
    ("app/plot/canvas.py", "os.environ"):
        "VTK's documented choice of EGL, set just before pyvista is imported when there is no display",
    ("app/plot/canvas.py", "pyvista.OFF_SCREEN"):
        "pyvista's documented switch for drawing off screen, set where pyvista is imported",
}

#: hooks of the standard library a patch replaces by assignment
HOOKS = {"signal.signal", "sys.unraisablehook", "sys.excepthook", "sys.displayhook", "sys.breakpointhook",
         "threading.excepthook", "warnings.showwarning", "warnings.formatwarning"}
#: calls that change the whole process
CALLS = {"signal.signal", "signal.set_wakeup_fd", "signal.pthread_sigmask", "signal.siginterrupt",
         "warnings.simplefilter", "warnings.filterwarnings", "warnings.resetwarnings", "logging.captureWarnings",
         "os.putenv", "os.unsetenv", "sys.setrecursionlimit", "sys.setswitchinterval", "sys.settrace",
         "sys.setprofile"}
#: mappings of the process whose entries a patch would change
MAPPINGS = {"os.environ", "sys.modules"}
MUTATORS = {"setdefault", "update", "pop", "popitem", "clear", "__setitem__", "__delitem__"}


def _imports(tree: ast.AST) -> dict[str, str]:
    """Local name -> the module or object it was imported as (``import a.b as c``: c -> a.b);
    names given ``self`` (``series = self``) -> ``self``."""
    names = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
            names.update({t.id: "self" for t in node.targets if isinstance(t, ast.Name)})
        elif isinstance(node, ast.Import):
            for a in node.names:
                names[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            for a in node.names:
                names[a.asname or a.name] = f"{node.module}.{a.name}"
    return names


def _dotted(node: ast.AST, names: dict[str, str]) -> str | None:
    """``a.b.c`` with ``a`` resolved through the imports, or None for anything but names and attributes."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([names.get(node.id, node.id), *reversed(parts)])


def _assigned(target: ast.AST, names: dict[str, str]) -> str | None:
    """What an assignment to ``target`` patches, or None."""
    if isinstance(target, ast.Subscript):
        return _dotted(target.value, names) if _dotted(target.value, names) in MAPPINGS else None
    if not isinstance(target, ast.Attribute):
        return None
    what = _dotted(target, names)
    if what in HOOKS:
        return what
    base = target.value
    if isinstance(base, ast.Name) and names.get(base.id, "app").split(".")[0] not in ("app", "self"):
        return what                                     # an attribute of an imported library (module, class)
    if isinstance(base, ast.Name) and base.id not in ("self", "cls") and names.get(base.id) != "self" \
            and target.attr.startswith("_") and not target.attr.startswith("__"):
        return ast.unparse(target)                      # a private attribute of another object (a module's function)
    return None


def _called(node: ast.Call, names: dict[str, str]) -> str | None:
    """What a call changes of the process, or None."""
    func = node.func
    what = _dotted(func, names)
    if what in CALLS:
        return what
    if isinstance(func, ast.Attribute) and func.attr == "addFilter":
        return ".addFilter"
    if isinstance(func, ast.Attribute) and func.attr in MUTATORS and _dotted(func.value, names) in MAPPINGS:
        return _dotted(func.value, names)
    if what == "setattr" and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant):
        fake = ast.Attribute(value=node.args[0], attr=str(node.args[1].value), ctx=ast.Store())
        return _assigned(fake, names)
    return None


def patches(root: pathlib.Path = ROOT) -> list[tuple[str, str, int]]:
    """Every process-wide change in app/: ``(file, what, line)``."""
    found = []
    for path in sorted((root / "app").rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = _imports(tree)
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Assign):
                targets = node.targets
            elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
                targets = [node.target]
            elif isinstance(node, ast.Delete):
                targets = node.targets
            for t in targets:
                for leaf in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    what = _assigned(leaf, names)
                    if what:
                        found.append((rel, what, node.lineno))
            if isinstance(node, ast.Call):
                what = _called(node, names)
                if what:
                    found.append((rel, what, node.lineno))
    return found


def test_the_scan_sees_what_it_forbids(tmp_path):
    """On a fake app/: hooks assigned (aliases and setattr too), signal handlers, a filter on a
    library's logger, the environment, sys.modules, a library's attribute and a private attribute
    of an object given by name (a module's function replaced); not an object's own state, an app
    module's, or a copy of the environment."""
    (tmp_path / "app").mkdir()
    (tmp_path / "app" / "x.py").write_text(
        "import os, sys, logging, warnings\n"
        "import signal as sg\n"
        "from signal import signal as handle\n"
        "import gmsh\n"
        "from app.common import interrupt\n"
        "sg.signal(sg.SIGINT, sg.SIG_IGN)\n"
        "handle(2, None)\n"
        "sys.unraisablehook = print\n"
        "warnings.showwarning = print\n"
        "setattr(sys, 'excepthook', print)\n"
        "logging.getLogger('ffcx').addFilter(None)\n"
        "os.environ['A'] = '1'\n"
        "os.environ.setdefault('B', '1')\n"
        "sys.modules['numpy'] = None\n"
        "gmsh.oldsig = None\n"
        "def f(module):\n"
        "    module._load_parameters = f\n"
        "class C:\n"
        "    def g(self):\n"
        "        self._x = 1\n"
        "        same = self\n"
        "        same._y = 2\n"
        "        self.part._z = 3\n"
        "        env = dict(os.environ, C='1')\n"
        "        interrupt.RECEIVED = []\n"
        "        return sg.getsignal(sg.SIGINT), env\n")
    assert sorted((line, what) for _, what, line in patches(tmp_path)) == [
        (6, "signal.signal"), (7, "signal.signal"), (8, "sys.unraisablehook"), (9, "warnings.showwarning"),
        (10, "sys.excepthook"), (11, ".addFilter"), (12, "os.environ"), (13, "os.environ"), (14, "sys.modules"),
        (15, "gmsh.oldsig"), (17, "module._load_parameters")]


def test_runtime_patches_are_made_behind_the_door():
    """A process-wide change anywhere in app/ but app/common/runtime.py (or an exception of
    :data:`EXCEPTIONS`, with its reason) fails here: put it in the door, documented there."""
    found = patches()
    outside = [f"{rel}:{line}: {what}" for rel, what, line in found if rel != DOOR and (rel, what) not in EXCEPTIONS]
    assert not outside, "runtime patches outside app/common/runtime.py:\n" + "\n".join(outside)
    seen = {(rel, what) for rel, what, _ in found}
    assert not set(EXCEPTIONS) - seen, f"exceptions that no longer occur: {set(EXCEPTIONS) - seen}"
    inside = {what for rel, what, _ in found if rel == DOOR}
    assert {"signal.signal", "sys.unraisablehook", "warnings.showwarning", ".addFilter", "os.environ",
            "gmsh.oldsig", "module._load_parameters"} <= inside, inside


def test_the_pinned_versions_are_installed(caplog):
    """The libraries are the versions the patches were written against: no DEBUG line."""
    from app.common import runtime
    runtime.import_gmsh()
    with caplog.at_level(logging.DEBUG, logger="app.common.runtime"):
        for distribution, module, series in (("fenics-ffcx", "ffcx", runtime.FENICS_SERIES),
                                             ("fenics-dolfinx", "dolfinx", runtime.FENICS_SERIES),
                                             ("gmsh", "gmsh", runtime.GMSH_SERIES)):
            assert runtime.pinned(distribution, module, series, patch="a patch", otherwise="skipped"), \
                runtime.installed_version(distribution, module)
    assert not caplog.records


def test_the_ffcx_log_filter_on_another_ffcx_is_attached_with_one_debug_line(monkeypatch, caplog):
    from app.common import runtime

    class Mark(logging.Filter):
        pass

    ffcx_log = logging.getLogger("ffcx")
    monkeypatch.setattr(ffcx_log, "filters", list(ffcx_log.filters))      # put back afterwards
    monkeypatch.setattr(runtime, "FENICS_SERIES", "9.9.")
    with caplog.at_level(logging.DEBUG, logger="app.common.runtime"):
        runtime.filter_ffcx_log(Mark)
        runtime.filter_ffcx_log(Mark)                                       # once per process
    assert sum(isinstance(f, Mark) for f in ffcx_log.filters) == 1
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "fenics-ffcx 9.9.x" in lines[0] and "attached all the same" in lines[0], lines


def test_the_settings_files_patch_on_another_version(monkeypatch, caplog):
    """A ``_load_parameters`` of another version is replaced all the same (a DEBUG line); one
    that is gone is an error, since the files might then be read where the app cannot see (the
    pinned DOLFINx/FFCx 0.5 have both)."""
    import dolfinx.jit
    import ffcx.parameters

    from app.common import runtime
    monkeypatch.setattr(dolfinx.jit, "_load_parameters", lambda: ({"cffi_verbose": True}, {}))
    monkeypatch.setattr(ffcx.parameters, "_load_parameters", lambda: ({"verbosity": 99}, {}))
    monkeypatch.setattr(runtime, "FENICS_SERIES", "9.9.")
    with caplog.at_level(logging.DEBUG, logger="app.common.runtime"):
        runtime.ignore_jit_settings_files()
    assert dolfinx.jit._load_parameters() == ({}, {}) and ffcx.parameters._load_parameters() == ({}, {})
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2, lines
    assert "dolfinx.jit" in lines[0] and "replaced all the same" in lines[0], lines
    monkeypatch.delattr(ffcx.parameters, "_load_parameters")
    with pytest.raises(RuntimeError, match="ffcx.parameters._load_parameters is gone"):
        runtime.ignore_jit_settings_files()


def test_gmsh_is_imported_without_touching_sigint_on_any_version():
    """Gmsh 4.8 sets SIGINT to its default action when imported: the program's handler stays
    (and finalize leaves it alone); with another Gmsh the same, with one DEBUG line."""
    code = ("import logging, signal, sys\n"
            "logging.basicConfig(level=logging.DEBUG, stream=sys.stdout, format='%(name)s: %(message)s')\n"
            "from app.common import runtime\n"
            "mine = lambda signum, frame: None\n"
            "signal.signal(signal.SIGINT, mine)\n"
            "runtime.GMSH_SERIES = sys.argv[1]\n"
            "gmsh = runtime.import_gmsh()\n"
            "gmsh.initialize(); gmsh.finalize()\n"
            "print('kept', signal.getsignal(signal.SIGINT) is mine, gmsh.oldsig)\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    for series, debug in (("4.8.", 0), ("9.9.", 1)):
        p = subprocess.run([sys.executable, "-c", code, series], cwd=ROOT, env=dict(env, PYTHONPATH=str(ROOT)),
                           capture_output=True, text=True, timeout=120)
        lines = p.stdout.splitlines()
        assert p.returncode == 0 and lines[-1] == "kept True None", (p.stdout, p.stderr)
        notes = [line for line in lines if line.startswith("app.common.runtime:")]
        assert len(notes) == debug and all("gmsh 9.9.x" in n and "all the same" in n for n in notes), lines


def test_the_command_line_sets_mpi_defaults_and_the_api_nothing(monkeypatch):
    """``install(command_line=True)`` under mpirun sets the MPI environment defaults (a user's own
    setting wins); ``install(command_line=False)`` changes nothing."""
    from app.common import runtime
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("OMPI_MCA_mpi_yield_when_idle", "0")
    before = dict(os.environ)
    runtime.install(command_line=False)
    assert dict(os.environ) == before
    runtime.install(command_line=True)
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1" and os.environ["OMPI_MCA_mpi_yield_when_idle"] == "0"


def test_run_study_installs_no_signal_handler_or_hook():
    """``app.run_study`` leaves a program's signal handlers, ``sys`` hooks and warnings machinery
    as they were (the command line's are installed only by ``python -m app``)."""
    import warnings

    # FFCx 0.5's import calls logging.captureWarnings(True): a library's own change, made for any
    # program that imports it, so it is imported before the hooks are taken below
    import ffcx  # noqa: F401

    import app
    mine = lambda signum, frame: None  # noqa: E731
    old = {s: signal.signal(s, mine) for s in (signal.SIGINT, signal.SIGTERM)}
    hooks = (sys.unraisablehook, sys.excepthook, warnings.showwarning)
    try:
        scene = app.load_scene({"name": "api", "mu": 4.0, "analyses": ["mceip_mu"],
                                "system": {"type": "two_particles", "k": 1000.0, "m": 2.0, "phi_deg": 35.0,
                                           "signs": [-1, 1]}})
        assert app.run_study(scene).states
        assert all(signal.getsignal(s) is mine for s in old)
        assert (sys.unraisablehook, sys.excepthook, warnings.showwarning) == hooks
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
