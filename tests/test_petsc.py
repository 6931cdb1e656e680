"""PETSc conventions: every solver has an options prefix and reads the command line's options;
only the command line fills PETSc's options database; every PETSc object the app creates is
destroyed, also when an analysis fails half-way (PETSc's own object counters)."""
from __future__ import annotations

import ast
import ctypes
import gc
from contextlib import contextmanager

import pytest
import yaml
from conftest import ROOT, one_error_line, run_cli, run_cli_here, run_scene
from petsc4py import PETSc

from app.common.petsc_options import PREFIXES, split_petsc_options

BLOCK = yaml.safe_load("""\
name: block
system: {type: block, nx: 4, ny: 2, nu: 0.3}
mu: 1.0
loading: {normal_force: 55.0, normal_steps: 2, tangential_step: 0.5, tangential_max: 1.0}
analyses: [necessary, sufficient, mceip_mu, mceip_lambda2]
""")


def _petsc_library() -> ctypes.CDLL:
    """The PETSc shared library this process has loaded (the one petsc4py uses)."""
    for line in open("/proc/self/maps", encoding="utf-8"):
        path = line.split()[-1]
        if "/libpetsc" in path and ".so" in path:
            return ctypes.CDLL(path)
    raise AssertionError("libpetsc is not loaded")


@contextmanager
def object_balance():
    """Yields a function giving (created, destroyed) PETSc objects since entering: PETSc's own
    counters petsc_numObjects / petsc_numObjectsDestroyed, kept while logging is on. petsc4py
    3.18 does not destroy an object that Python drops (it only queues it as garbage), so a
    balance of zero means every object was destroyed by the app."""
    lib = _petsc_library()
    created = ctypes.c_int.in_dll(lib, "petsc_numObjects")
    destroyed = ctypes.c_int.in_dll(lib, "petsc_numObjectsDestroyed")
    PETSc.Log.begin()
    gc.collect()
    c0, d0 = created.value, destroyed.value
    yield lambda: (created.value - c0, destroyed.value - d0)


def test_the_counters_see_a_leak():
    """The balance detects an object that is dropped instead of destroyed."""
    with object_balance() as balance:
        v = PETSc.Vec().createSeq(3, comm=PETSc.COMM_SELF)
        del v
        gc.collect()
        created, destroyed = balance()
    assert (created, destroyed) == (1, 0)
    PETSc.garbage_cleanup(PETSc.COMM_SELF)


def test_a_study_destroys_every_object():
    with object_balance() as balance:
        results = run_scene(BLOCK)
        gc.collect()
        created, destroyed = balance()
    assert not results["failures"]
    assert created > 100 and created == destroyed, (created, destroyed)


def _failing_from_options(monkeypatch, module, prefix: str) -> None:
    """Make ``module``'s solvers with options prefix ``prefix`` raise PETSc.Error once configured."""
    real = module.from_options

    def from_options(obj):
        real(obj)
        if obj.getOptionsPrefix() == prefix:
            raise PETSc.Error(76)       # PETSC_ERR_LIB: "error in external library"
        return obj
    monkeypatch.setattr(module, "from_options", from_options)


@pytest.mark.parametrize("analysis, module, prefix", [
    ("sufficient", "app.analyses.conditions.full_size", "cd_sufficient_"),
    ("necessary", "app.analyses.conditions.full_size", "cd_necessary_"),
], ids=["sufficient", "necessary"])
def test_a_failing_analysis_leaks_nothing(monkeypatch, analysis, module, prefix):
    import importlib
    _failing_from_options(monkeypatch, importlib.import_module(module), prefix)
    # without MCEIP-lambda^2, which would decide the sufficient condition without an eigensolver
    scene = dict(BLOCK, analyses=["necessary", "sufficient", "mceip_mu"])
    with object_balance() as balance:
        results = run_scene(scene)
        gc.collect()
        created, destroyed = balance()
    failed = {f["analysis"] for f in results["failures"]}
    assert analysis in failed, results["failures"]          # the failure was reached and recorded
    assert created > 100 and created == destroyed, (created, destroyed)


def test_a_failing_loading_path_leaks_nothing(monkeypatch):
    import app.loading.contact as contact
    from app.linalg import from_options as real

    def from_options(obj):
        real(obj)
        raise PETSc.Error(76)
    monkeypatch.setattr(contact, "from_options", from_options)
    scene = dict(BLOCK, loading=dict(BLOCK["loading"], tangential_max=3.0))
    with object_balance() as balance:
        with pytest.raises(PETSc.Error):
            run_scene(scene)
        gc.collect()
        created, destroyed = balance()
    assert created > 10 and created == destroyed, (created, destroyed)


def test_every_solver_gets_a_prefix():
    """Every ``KSP().create``, ``SNES().create``, ``EPS().create`` in app/ is wrapped in
    ``with_prefix(...)``, and every prefix of PREFIXES is given to some solver."""
    used, bare = set(), []
    for path in sorted((ROOT / "app").rglob("*.py")):
        if path.name == "petsc_options.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        wrapped = {id(node.args[0]) for node in ast.walk(tree)
                   if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "with_prefix"}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and node.value in PREFIXES:
                used.add(node.value)
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "create"
                    and isinstance(node.func.value, ast.Call)
                    and getattr(node.func.value.func, "attr", "") in ("KSP", "SNES", "EPS")
                    and id(node) not in wrapped):
                bare.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert bare == [], f"solvers without an options prefix: {bare}"
    assert used == set(PREFIXES), used ^ set(PREFIXES)


def test_a_run_leaves_the_options_database_as_it_was():
    """Nothing the app does (nor anything in a scene file) writes PETSc options."""
    before = PETSc.Options().getAll()
    run_scene(BLOCK)
    assert PETSc.Options().getAll() == before


@pytest.mark.parametrize("key", ["petsc_options", "-cd_necessary_eps_monitor"])
def test_a_scene_cannot_carry_petsc_options(scene_file, key):
    text = yaml.safe_dump({**BLOCK, key: "-cd_necessary_eps_monitor"})
    err = one_error_line(run_cli_here("validate", str(scene_file(text))))
    assert f"'{key}'" in err and "unknown key" in err, err


def test_split_petsc_options():
    rest, petsc = split_petsc_options(["run", "s.yaml", "-cd_necessary_eps_tol", "1e-10", "-o", "out",
                                       "-cd_loading_snes_monitor", "-log_view", "-cd_mcp_ksp_rtol", "-1e-3"])
    assert rest == ["run", "s.yaml", "-o", "out"]
    assert petsc == ["-cd_necessary_eps_tol", "1e-10", "-cd_loading_snes_monitor", "-log_view",
                     "-cd_mcp_ksp_rtol", "-1e-3"]
    # a scene file is never taken as an option's value
    assert split_petsc_options(["run", "-cd_necessary_eps_monitor", "s.yaml"]) == \
        (["run", "s.yaml"], ["-cd_necessary_eps_monitor"])
    with pytest.raises(ValueError, match="unknown options prefix"):
        split_petsc_options(["run", "-cd_neccessary_eps_monitor"])


def test_cli_rejects_unknown_prefix_and_options_in_one_line():
    err = one_error_line(run_cli_here("run", "-cd_neccessary_eps_monitor"))
    assert "-cd_neccessary_eps_monitor" in err and "cd_necessary_" in err
    err = one_error_line(run_cli_here("run", "--bogus"))
    assert "unrecognized arguments: --bogus" in err


@pytest.mark.slow
def test_cli_passes_petsc_options_to_slepc(tmp_path):
    """``python -m app run app/scenes/villechaise_block.yaml -cd_necessary_eps_monitor`` prints
    SLEPc's monitor (and nothing of the other solvers); the answers are unchanged."""
    scene = ROOT / "app" / "scenes" / "villechaise_block.yaml"
    proc = run_cli("run", str(scene), "-q", "-o", str(tmp_path / "out"), "-cd_necessary_eps_monitor",
                   "-cd_flex_ksp_view")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    monitor = [ln for ln in lines if " EPS nconv=" in ln]
    assert len(monitor) > 10, proc.stdout[-2000:]
    assert "KSP Object: (cd_flex_)" in proc.stdout
    assert "SNES Function norm" not in proc.stdout
    import json
    final = json.loads((tmp_path / "out" / "results.json").read_text())["states"][-1]
    assert (final["classification"]["stick"], final["classification"]["slip"]) == (0, 17)
    assert final["analyses"]["mceip_mu"]["solutions"][0]["value"] == pytest.approx(1.7048, abs=5e-5)


def test_prefixes_are_documented():
    for doc in (ROOT / "README.md", ROOT / "docs" / "petsc.md"):
        text = doc.read_text(encoding="utf-8")
        for prefix in PREFIXES:
            assert f"`{prefix}`" in text, (doc.name, prefix)
