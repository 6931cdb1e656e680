"""Nothing lost, nothing silently wrong (issue 10): output-folder safety, resource limits,
frictionless physics, physical sanity, strict input, file modes, mesh cache fallback.

Each test names the acceptance point it checks. The CLI tests that run a study, hold locks or
set process limits run ``python -m app`` in a subprocess (conftest.run_cli); those refused
before any work, and the failure-injection tests (one writer patched to fail as a full disk
would), call ``app.cli.main.main`` in this process (conftest.run_cli_here).
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import pathlib
import signal
import stat
import subprocess
import time

import numpy as np
import pytest
from conftest import PY, ROOT, fill_disk, run_cli, run_cli_here, tmpfs

TP = """\
name: tp
system: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}
mu: 2.5
analyses: [necessary, sufficient, mceip_mu]
"""
BLOCK = """\
name: blk
system: {type: block, nx: 10, ny: 5}
mu: MU
loading: {normal_force: 55.0, normal_steps: 3, tangential_step: 0.1, tangential_max: 1.5}
analyses: [necessary, sufficient, mceip_mu, mceip_lambda2]
"""


def _snapshot(folder: pathlib.Path) -> dict:
    """Every entry under ``folder`` (hidden ones too) with a hash of its bytes."""
    out = {}
    for p in sorted(folder.rglob("*")):
        out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
    return out


def _one_error_line(proc, code: int = 2) -> str:
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    assert proc.returncode == code, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    return lines[0]


def _no_litter(parent: pathlib.Path) -> None:
    left = [p.name for p in parent.iterdir() if ".partial-" in p.name or p.name.endswith(".lock")]
    assert left == []


# ---------------------------------------------------------------------------------------------
# The app only ever replaces what it wrote


def test_overwrite_refuses_a_folder_with_unrelated_files(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    mine = tmp_path / "thesis"
    (mine / "chapter").mkdir(parents=True)
    (mine / "thesis.tex").write_text("my work")
    (mine / "chapter" / "results.json").write_text("{}")          # even a file named like ours
    (mine / ".hidden").write_text("x")
    before = _snapshot(mine)
    for extra in (["--overwrite"], []):
        line = _one_error_line(run_cli_here("run", str(scene), "-o", str(mine), "-q", *extra))
        assert "holds other files" in line and "holds results" not in line and "already holds" not in line
        assert _snapshot(mine) == before
    _no_litter(tmp_path)


def test_overwrite_on_the_current_folder_holding_the_scene_deletes_nothing(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text(TP)
    before = _snapshot(tmp_path)
    for target in (str(tmp_path), ".", "./", str(tmp_path.parent)):
        line = _one_error_line(run_cli_here("run", "scene.yaml", "-o", target, "--overwrite", "-q", cwd=tmp_path))
        assert "current folder" in line or "holds other files" in line
        assert _snapshot(tmp_path) == before


def test_empty_current_folder_is_refused_before_the_work(tmp_path):
    """Renaming results over '.' cannot work: refused at once, not after the run."""
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    empty = tmp_path / "empty"
    empty.mkdir()
    line = _one_error_line(run_cli_here("run", str(scene), "-o", ".", "-q", cwd=empty))
    assert "current folder" in line
    assert list(empty.iterdir()) == []


def test_overwrite_replaces_only_the_apps_own_folder(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    out = tmp_path / "out"
    out.mkdir()                                           # an empty folder is used
    assert run_cli_here("run", str(scene), "-o", str(out), "-q").returncode == 0
    marker = json.loads((out / ".contact-divergence.json").read_text())
    assert marker["app"] == "contact-divergence" and marker["kind"] == "results" and marker["format"] >= 1
    line = _one_error_line(run_cli_here("run", str(scene), "-o", str(out), "-q"))
    assert "already holds results of this app" in line and "--overwrite" in line
    (out / "results.json").write_text("old")
    assert run_cli_here("run", str(scene), "-o", str(out), "-q", "--overwrite").returncode == 0
    assert json.loads((out / "results.json").read_text())["scene"] == "tp"
    _no_litter(tmp_path)
    assert json.loads((out / ".contact-divergence.json").read_text())["entries"] == \
        ["proofs", "results.json", "steps.csv"]
    # a user file added to the app's folder makes it "other": never replaced again
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    line = _one_error_line(run_cli_here("run", str(scene), "-o", str(out), "-q", "--overwrite"))
    assert "holds other files (notes.txt besides this app's results)" in line
    assert _snapshot(out) == before
    (out / "notes.txt").unlink()
    (out / ".contact-divergence.json").unlink()           # without the marker: not ours either
    line = _one_error_line(run_cli_here("run", str(scene), "-o", str(out), "-q", "--overwrite"))
    assert "holds other files" in line and (out / "results.json").exists()


def test_bad_output_paths_give_one_line(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    for target in ("/proc/x", str(tmp_path / ("n" * 300)), str(tmp_path / "s.yaml" / "out")):
        line = _one_error_line(run_cli_here("run", str(scene), "-o", target, "-q"))
        assert target[:20] in line
    assert scene.read_text() == TP


# ---------------------------------------------------------------------------------------------
# Fail before the work, never after it


def test_commit_failure_keeps_the_staged_results(tmp_path):
    """The target gains a user's file during the run: the commit refuses, the results stay staged."""
    from app.io.folder import CommitError, ResultsFolder
    out = tmp_path / "out"
    folder = ResultsFolder(out, overwrite=False)
    assert folder.check() is None
    (folder.staging / "results.json").write_text('{"scene": "x"}')
    out.mkdir()
    (out / "user.txt").write_text("mine")                 # appears while the study runs
    with pytest.raises(CommitError) as err:
        folder.commit()
    msg = str(err.value)
    assert str(folder.staging) in msg and "\n" not in msg
    folder.abort()                                        # the CLI's cleanup must keep them
    assert (folder.staging / "results.json").read_text() == '{"scene": "x"}'
    assert (out / "user.txt").read_text() == "mine" and sorted(os.listdir(out)) == ["user.txt"]


def test_commit_rename_failure_in_the_cli_keeps_results_and_exits_nonzero(tmp_path, monkeypatch, capsys):
    import app.io.folder as folder_mod
    from app.cli.main import main
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    out = tmp_path / "out"
    real = os.rename

    def failing_rename(src, dst, *a, **k):
        if pathlib.Path(dst) == out:
            raise OSError(errno.EXDEV, "Invalid cross-device link", str(src))
        return real(src, dst, *a, **k)
    monkeypatch.setattr(folder_mod.os, "rename", failing_rename)
    code = main(["run", str(scene), "-o", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 4 and len(err.splitlines()) == 1 and "kept in" in err
    staged = pathlib.Path(err.split("kept in ")[1].strip())
    assert json.loads((staged / "results.json").read_text())["scene"] == "tp"
    assert not out.exists()


def test_two_concurrent_runs_to_one_folder_one_is_refused(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK.replace("MU", "1.1").replace("tangential_max: 1.5", "tangential_max: 3.0"))
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    first = subprocess.Popen([PY, "-m", "app", "run", str(scene), "-o", str(out), "-q"], cwd=ROOT, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # the staging folder appears only once the lock is held: the lock file alone is created a moment
    # before it is locked, and a run stopped in that moment lets the second one take the lock
    t0 = time.time()
    while not list(tmp_path.glob(".out.partial-*")) and first.poll() is None and time.time() - t0 < 60:
        time.sleep(0.01)
    # the first run is held while the second starts (its start-up alone can outlast a small study)
    os.kill(first.pid, signal.SIGSTOP)
    try:
        second = run_cli("run", str(scene), "-o", str(out), "-q")
    finally:
        os.kill(first.pid, signal.SIGCONT)
    rc1 = first.wait(timeout=300)
    assert rc1 == 0, first.stderr.read()
    line = _one_error_line(second)
    assert "another run is writing" in line
    assert json.loads((out / "results.json").read_text())["scene"] == "blk"
    _no_litter(tmp_path)


def test_a_users_file_named_like_the_lock_is_kept(tmp_path):
    """A file ``.out.lock`` the app did not create (a user's own) is locked during the run but
    neither written nor removed; the run's own lock file is removed as before."""
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    users = tmp_path / ".out.lock"
    users.write_text("my notes\n")
    users.chmod(0o444)
    assert run_cli_here("run", str(scene), "-o", str(tmp_path / "out"), "-q").returncode == 0
    assert users.read_text() == "my notes\n" and (tmp_path / "out" / "results.json").exists()
    assert run_cli_here("run", str(scene), "-o", str(tmp_path / "out2"), "-q").returncode == 0
    assert not (tmp_path / ".out2.lock").exists()


def test_a_held_lock_refuses_the_run_and_the_sweep(tmp_path):
    from app.io.folder import FolderLock
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(TP + "sweep: {parameters: {mu: [1.0, 2.0]}}\n")
    for sc, out in ((scene, tmp_path / "out"), (sweep, tmp_path / "swout")):
        lock = FolderLock(out)
        assert lock.acquire() is None
        try:
            line = _one_error_line(run_cli("run", str(sc), "-o", str(out), "-q"))
            assert "another run is writing" in line and not out.exists()
        finally:
            lock.release()


def _enospc(*a, **k):
    raise OSError(errno.ENOSPC, "No space left on device", "results.json")


@pytest.mark.parametrize("where", ["results", "pictures", "memory"])
def test_full_disk_or_no_memory_gives_one_line(tmp_path, monkeypatch, capsys, where):
    """ENOSPC from our writer, an HDF5-style RuntimeError, a MemoryError: one line, exit 4, nothing left."""
    import app.io.results as results_mod
    import app.plot.pictures as pictures_mod
    import app.study.run as study_mod
    from app.cli.main import main
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    out = tmp_path / "out"
    if where == "results":
        monkeypatch.setattr(results_mod, "write_results", _enospc)
    elif where == "pictures":                # as h5py/HDF5 report it
        def h5(*a, **k):
            raise RuntimeError("Can't write data (file write failed: errno = 28, error message = "
                               "'No space left on device')")
        monkeypatch.setattr(pictures_mod, "draw_after_run", h5)
    else:
        def oom(*a, **k):
            raise MemoryError()
        monkeypatch.setattr(study_mod, "study", oom)
    code = main(["run", str(scene), "-o", str(out), "-q"])
    cap = capsys.readouterr()
    assert code == 4
    lines = cap.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in cap.err + cap.out
    assert ("out of memory" if where == "memory" else "no space left") in lines[0]
    assert not out.exists()
    _no_litter(tmp_path)


@pytest.mark.slow
def test_full_tmpfs_during_the_run(tmp_path):
    """A real full disk (a 64 MB tmpfs filled once the run is writing its fields): one line, exit 4,
    the staging folder removed. Skipped where tmpfs cannot be mounted."""
    with tmpfs(tmp_path / "mnt", "64m") as mnt:
        proc = None
        try:
            scene = tmp_path / "s.yaml"
            scene.write_text(BLOCK.replace("MU", "1.1") + "outputs: {paraview: true, plots: true, report: true}\n")
            env = dict(os.environ, PYTHONPATH=str(ROOT))
            proc = subprocess.Popen([PY, "-m", "app", "run", str(scene), "-o", str(mnt / "out"), "-q"], cwd=ROOT,
                                    env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            t0 = time.time()
            while not list(mnt.glob(".out.partial-*/paraview")) and proc.poll() is None and time.time() - t0 < 120:
                time.sleep(0.005)
            fill_disk(mnt)
            stdout, stderr = proc.communicate(timeout=300)
            (mnt / "fill").unlink()
            assert proc.returncode == 4, (stdout, stderr)
            assert len(stderr.splitlines()) == 1 and "no space left" in stderr and "Traceback" not in stderr
            assert sorted(os.listdir(mnt)) == []
        finally:
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()


def test_disk_preflight_refuses_before_the_work(tmp_path):
    with tmpfs(tmp_path / "mnt", "1m") as mnt:
        scene = tmp_path / "s.yaml"
        scene.write_text(TP)
        line = _one_error_line(run_cli_here("run", str(scene), "-o", str(mnt / "out"), "-q"))
        assert "not enough free space" in line and str(mnt / "out") in line
        assert os.listdir(mnt) == []


# ---------------------------------------------------------------------------------------------
# Resource pre-flight


def test_preflight_refuses_ten_billion_states_within_a_second(tmp_path):
    from app.scene import limits as preflight
    from app.scene.schema import SceneError, load_scene
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK.replace("MU", "1.1").replace("tangential_step: 0.1", "tangential_step: 1.0e-9")
                     .replace("tangential_max: 1.5", "tangential_max: 10.0"))
    t0 = time.perf_counter()
    with pytest.raises(SceneError) as err:
        preflight.check(load_scene(scene))
    assert time.perf_counter() - t0 < 1.0                 # arithmetic only (measured: milliseconds)
    assert "loading.tangential_step" in str(err.value) and "10000000003" in str(err.value)
    for args in (["validate", str(scene)], ["run", str(scene), "-o", str(tmp_path / "out")]):
        t0 = time.perf_counter()
        line = _one_error_line(run_cli_here(*args))
        print(f"{args[0]}: refused in {time.perf_counter() - t0:.2f} s (app.cli.main.main in this process)")
        assert "loading.tangential_step = 1e-09" in line and "settings.limits.max_states" in line
    assert not (tmp_path / "out").exists()


def test_small_address_space_cap_is_refused_before_the_work(tmp_path):
    """Under ``ulimit -v`` below what DOLFINx/PETSc/MPI map, the mesh creation was seen spinning
    for minutes; the pre-flight refuses it with one line instead (and nothing is written)."""
    import resource
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK.replace("MU", "1.1"))
    cap = 800_000 * 1024

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    p = subprocess.run([PY, "-m", "app", "run", str(scene), "-o", str(tmp_path / "out")], capture_output=True,
                       text=True, timeout=120, env=env, cwd=ROOT, preexec_fn=limit)
    assert time.perf_counter() - t0 < 60
    line = _one_error_line(p)
    assert "address-space limit (ulimit -v)" in line and "0.76 GiB" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("edit, needles", [
    ("system: {type: block, nx: 4096, ny: 4096}", ("system.nx = 4096", "settings.limits.max_dofs")),
    ("system: {type: block, nx: 3000, ny: 1}", ("system.nx = 3000", "memory estimate")),
    ("system: {type: block, pattern: unstructured, mesh_size: 0.01}", ("system.mesh_size = 0.01", "DOFs")),
])
def test_preflight_names_the_key(tmp_path, edit, needles):
    scene = tmp_path / "s.yaml"
    text = BLOCK.replace("MU", "1.1").replace("system: {type: block, nx: 10, ny: 5}", edit)
    if "3000" in edit:
        text += "settings: {limits: {max_memory_gb: 0.5}}\n"
    scene.write_text(text)
    line = _one_error_line(run_cli_here("validate", str(scene)))
    for n in needles:
        assert n in line


def test_limits_are_configurable_and_estimates_printed(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK.replace("MU", "1.1") + "settings: {limits: {max_states: 5}}\n")
    line = _one_error_line(run_cli_here("validate", str(scene)))
    assert "settings.limits.max_states = 5" in line
    scene.write_text(BLOCK.replace("MU", "1.1") + "settings: {limits: {max_states: 100}}\n")
    p = run_cli_here("validate", str(scene))
    assert p.returncode == 0 and "18 load states" in p.stdout and "DOFs" in p.stdout and "GiB" in p.stdout
    p = run_cli_here("run", str(scene), "-o", str(tmp_path / "o"), "-q", "--log-level", "INFO")
    assert p.returncode == 0 and "INFO: pre-flight: at most 18 load states, 232 DOFs, 11 contact nodes" in p.stderr


@pytest.mark.parametrize("settings, key", [
    ("{mcp: {starts: [" + ", ".join(["1.0"] * 101) + "]}}", "settings.mcp.starts"),
    ("{eig: {dense_limit: 1000000000}}", "settings.eig.dense_limit"),
    ("{eig: {nev: 100000}}", "settings.eig.nev"),
    ("{mcp: {pattern_eig_limit: 100000000}}", "settings.mcp.pattern_eig_limit"),
    ("{limits: {max_states: 0}}", "settings.limits.max_states"),
])
def test_numeric_settings_are_bounded(tmp_path, settings, key):
    scene = tmp_path / "s.yaml"
    scene.write_text(TP + f"settings: {settings}\n")
    assert key in _one_error_line(run_cli_here("validate", str(scene)))


# ---------------------------------------------------------------------------------------------
# Strict input


@pytest.mark.parametrize("text, needles", [
    (TP + "mu: 3.0\n", ("duplicate key 'mu'", "line 3", "line 5")),
    ("name: a\nsystem:\n  type: block\n  nx: 4\n  nx: 5\nmu: 1\n", ("duplicate key 'nx'", "line 4", "line 5")),
    (TP.replace("mu: 2.5", "mu: yes"), ("mu = True", "boolean", "number")),
    (TP.replace("mu: 2.5", "mu: on"), ("mu = True", "boolean")),
    (BLOCK.replace("MU", "1").replace("nx: 10", "nx: true"), ("system.nx = True", "boolean", "integer")),
    (BLOCK.replace("MU", "1").replace("normal_steps: 3", "normal_steps: false"), ("loading.normal_steps",)),
    (TP.replace("k: 1000.0", "k: true"), ("system.k = True", "boolean")),
    (TP + "settings: {mcp: {starts: [1.0, true]}}\n", ("settings.mcp.starts", "boolean")),
    (TP.replace("name: tp", "name: " + "n" * 240), ("name = ", "at most 100 characters")),
])
def test_strict_input(tmp_path, text, needles):
    scene = tmp_path / "s.yaml"
    scene.write_text(text)
    line = _one_error_line(run_cli_here("validate", str(scene)))
    for n in needles:
        assert n in line


def test_merge_keys_are_not_duplicates():
    import yaml

    from app.scene.schema import _UniqueKeyLoader
    data = yaml.load("a: &b {k: 1, m: 2}\nc: {<<: *b, k: 3}\n", Loader=_UniqueKeyLoader)
    assert data["c"] == {"k": 3, "m": 2}


def test_non_regular_and_oversized_scene_files_are_refused_unread(tmp_path):
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    big = tmp_path / "big.yaml"
    big.write_text(TP + "#" * (2 << 20) + "\n")
    for path, needle in (("/dev/zero", "not a regular file"), (str(fifo), "not a regular file"),
                         (str(big), "at most 1048576 bytes")):
        t0 = time.perf_counter()
        p = run_cli("validate", path, timeout=60)
        line = _one_error_line(p)
        assert needle in line and time.perf_counter() - t0 < 30


def test_version():
    p = run_cli("--version")
    from app import __version__
    assert p.returncode == 0 and p.stdout.strip() == f"contact-divergence {__version__}"
    toml = (ROOT / "pyproject.toml").read_text()
    assert f'version = "{__version__}"' in toml


# ---------------------------------------------------------------------------------------------
# Sharing: file modes and the mesh cache


@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_every_output_file_honours_the_umask(tmp_path, umask):
    scene = tmp_path / "s.yaml"
    scene.write_text(TP + "outputs: {plots: true, report: true}\n")
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(TP + "sweep: {parameters: {mu: [1.0, 2.0]}}\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for sc, out in ((scene, tmp_path / "out"), (sweep, tmp_path / "swout")):
        p = subprocess.run(["sh", "-c", f'umask {umask:03o} && exec "$0" -m app run "$1" -o "$2" -q',
                            PY, str(sc), str(out)], capture_output=True, text=True, env=env, cwd=ROOT)
        assert p.returncode == 0, p.stderr
        files = [f for f in out.rglob("*") if f.is_file()]
        names = {f.name for f in files}
        assert {"results.json", ".contact-divergence.json"} <= names
        assert ("steps.csv" in names) or ({"sweep.csv", "sweep.json"} <= names)
        modes = {str(f.relative_to(out)): stat.S_IMODE(f.stat().st_mode) for f in files}
        assert set(modes.values()) == {0o666 & ~umask}, modes


def test_mesh_cache_falls_back_to_the_user_cache(tmp_path, monkeypatch):
    """The install folder cannot be written (here: it would be under a regular file, which even
    root cannot create): new meshes go to $XDG_CACHE_HOME/contact-divergence/meshes."""
    from mpi4py import MPI

    import app.systems.block.mesh as bm
    blocker = tmp_path / "install"
    blocker.write_text("a file, not a folder")
    monkeypatch.setattr(bm, "DEFAULT_CACHE_DIR", blocker / "meshes")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    name = bm.mesh_file_name(80.0, 40.0, 3, 2, "right", None)
    assert bm.mesh_cache_path(name) == tmp_path / "xdg" / "contact-divergence" / "meshes" / name
    mesh, _ = bm.block_mesh(MPI.COMM_WORLD, 80.0, 40.0, 3, 2, "right")
    assert mesh.topology.index_map(2).size_global == 12
    cached = list((tmp_path / "xdg" / "contact-divergence" / "meshes").iterdir())
    assert [p.name for p in cached] == [name]             # written atomically: no temporary left
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert bm.user_cache_dir() == tmp_path / "home" / ".cache" / "contact-divergence" / "meshes"
    # a writable install folder is used as before
    monkeypatch.setattr(bm, "DEFAULT_CACHE_DIR", tmp_path / "meshes")
    assert bm.mesh_cache_path(name) == tmp_path / "meshes" / name


# ---------------------------------------------------------------------------------------------
# Sweep folders


def test_sweep_refuses_a_folder_with_other_files_and_resumes_its_own(tmp_path):
    sweep = tmp_path / "sw.yaml"
    sweep.write_text(TP + "sweep: {parameters: {mu: [1.0, 2.0]}}\n")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "sweep.csv").write_text("my,data\n")
    before = _snapshot(mine)
    for extra in ([], ["--overwrite"]):
        line = _one_error_line(run_cli_here("run", str(sweep), "-o", str(mine), "-q", *extra))
        assert "holds other files" in line
        assert _snapshot(mine) == before
    out = tmp_path / "out"
    assert run_cli_here("run", str(sweep), "-o", str(out), "-q").returncode == 0
    p = run_cli_here("run", str(sweep), "-o", str(out))
    assert p.returncode == 0 and "2 skipped" in p.stdout
    # a single study's folder is not a sweep folder, and a sweep folder is not a study's
    single = tmp_path / "single"
    scene = tmp_path / "s.yaml"
    scene.write_text(TP)
    assert run_cli_here("run", str(scene), "-o", str(single), "-q").returncode == 0
    assert "not a sweep" in _one_error_line(run_cli_here("run", str(sweep), "-o", str(single), "-q"))
    line = _one_error_line(run_cli_here("run", str(scene), "-o", str(out), "-q", "--overwrite"))
    assert "holds other files" in line or "sweep" in line
    assert (out / "sweep.csv").exists()


# ---------------------------------------------------------------------------------------------
# Frictionless and degenerate friction


def _state(r_T, r_N, u_N=None):
    from app.loading.state import EquilibriumState
    r_T, r_N = np.asarray(r_T, float), np.asarray(r_N, float)
    u_N = np.zeros_like(r_N) if u_N is None else np.asarray(u_N, float)
    return EquilibriumState(index=0, load={}, u_T=np.zeros_like(r_T), u_N=u_N, r_T=r_T, r_N=r_N)


def test_roundoff_tangential_reaction_has_no_sign():
    from app.loading.classify import classify, frictionless_reason
    rng = np.random.default_rng(0)
    for scale in (1.0, 1e-3, 1e6):
        r_N = -scale * np.array([3.0, 5.0, 2.0, 0.0])
        r_T = scale * 1e-16 * rng.standard_normal(4)
        cls = classify(_state(r_T, r_N, u_N=[0, 0, 0, -1.0]), 0.0)
        assert cls.status == ("slip", "slip", "slip", "free") and cls.signs == (0, 0, 0, 0)
        assert frictionless_reason(cls, 0.0).startswith("not applicable: frictionless")
        assert classify(_state(-r_T, r_N, u_N=[0, 0, 0, -1.0]), 0.0) == cls   # round-off sign irrelevant


def test_cone_boundary_from_both_sides_and_in_any_units():
    from app.loading.classify import classify
    mu, rtol = 1.1, 1e-8
    for scale in (1.0, 1e-3, 1e3):
        r_N = -scale * np.array([10.0, 10.0, 10.0, 10.0, 10.0])
        ratio = np.array([1 + 0.5 * rtol, 1 - 0.5 * rtol, 1 - 50 * rtol, 1 + 50 * rtol, 0.5])
        r_T = -mu * r_N * ratio * np.array([1, -1, 1, -1, 1])
        cls = classify(_state(r_T, r_N), mu, rtol)
        assert cls.status == ("slip", "slip", "stick", "slip", "stick")
        assert cls.signs == (1, -1, 0, -1, 0)


def test_frictionless_two_particles_reports_not_applicable():
    from conftest import run_scene
    res = run_scene({"name": "tp0", "system": {"type": "two_particles", "k": 1000.0, "m": 2.0, "phi_deg": 35.0,
                                               "signs": [1, -1]}, "mu": 0.0,
                     "analyses": ["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]})
    a = res["states"][0]["analyses"]
    assert set(a) == {"necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"}
    for v in a.values():
        assert v == {"not_applicable": True, "reason": "not applicable: frictionless (K* = K0 is SPD, no divergence)"}
    assert [n["sign"] for n in res["states"][0]["nodes"]] == [0, 0]


def _frictionless_view(res):
    return [(tuple(n["status"] for n in s["nodes"]), tuple(n["sign"] for n in s["nodes"]),
             json.dumps(s["analyses"], sort_keys=True)) for s in res["states"]]


@pytest.fixture(scope="module")
def frictionless_serial(tmp_path_factory):
    d = tmp_path_factory.mktemp("mu0")
    (d / "s.yaml").write_text(BLOCK.replace("MU", "0"))
    p = run_cli_here("run", str(d / "s.yaml"), "-o", str(d / "out1"))
    assert p.returncode == 0, p.stderr
    return d, json.loads((d / "out1" / "results.json").read_text()), p.stdout


def test_frictionless_block_has_no_critical_values(frictionless_serial):
    d, res, stdout = frictionless_serial
    for s in res["states"]:
        for v in s["analyses"].values():
            assert v.get("not_applicable") and "solutions" not in v and "lambda2" not in v
        assert all(n["sign"] == 0 for n in s["nodes"])
    assert "MCEIP-mu first" not in stdout and "not applicable: frictionless" in stdout
    steps = (d / "out1" / "steps.csv").read_text().splitlines()
    head = steps[0].split(",")
    for row in steps[1:]:
        cells = dict(zip(head, row.split(",")))
        assert cells["mceip_mu_min"] == cells["mceip_mu_count"] == cells["sufficient_max_lambda2 [1/s^2]"] == ""


@pytest.mark.mpi
@pytest.mark.slow
def test_frictionless_same_output_on_two_ranks(frictionless_serial):
    d, ref, _ = frictionless_serial
    p = run_cli("run", str(d / "s.yaml"), "-o", str(d / "out2"), "-q", ranks=2)
    assert p.returncode == 0, p.stderr
    res = json.loads((d / "out2" / "results.json").read_text())
    assert res["mpi_ranks"] == 2
    assert _frictionless_view(res) == _frictionless_view(ref)
    for a, b in zip(ref["states"], res["states"]):
        for na, nb in zip(a["nodes"], b["nodes"]):
            assert nb["r_N"] == pytest.approx(na["r_N"], rel=1e-8, abs=1e-10 * 55)
            assert abs(nb["r_T"] - na["r_T"]) <= 1e-10 * 55


# ---------------------------------------------------------------------------------------------
# Physical sanity


@pytest.mark.parametrize("edit, needle", [
    ("normal_force: 55.0", "normal_force: 5000.0"),
    ("nx: 10, ny: 5", "nx: 10, ny: 5, E: 1.0e-300"),
])
def test_small_strain_violations_are_warned(tmp_path, edit, needle):
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK.replace("MU", "1.1").replace(edit, needle).replace(
        "[necessary, sufficient, mceip_mu, mceip_lambda2]", "[necessary]") + "outputs: {report: true}\n")
    p = run_cli_here("run", str(scene), "-o", str(tmp_path / "out"))
    assert p.returncode == 0, p.stderr
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    w = [x for x in res["warnings"] if "small-strain" in x]
    assert len(w) == 1 and "state 0" in w[0] and "state 2" in w[0] and "%" in w[0]
    assert "WARNING: small-strain" in p.stdout
    assert "small-strain" in (tmp_path / "out" / "report.md").read_text()


def test_sane_paths_have_no_strain_warning():
    from app.loading.sanity import check_block_path
    from app.loading.state import EquilibriumState
    st = [EquilibriumState(index=i, load={"u_x": -0.1 * i, "u_y": -0.5}, u_T=np.full(3, -0.1 * i),
                           u_N=np.zeros(3), r_T=np.zeros(3), r_N=-np.ones(3)) for i in range(5)]
    assert check_block_path(st, 80.0, 40.0) == []
    # the same path in metres on a 4 cm block: identical (relative measures)
    st_m = [EquilibriumState(index=s.index, load={"u_x": s.load["u_x"] / 1000, "u_y": s.load["u_y"] / 1000},
                             u_T=s.u_T / 1000, u_N=s.u_N, r_T=s.r_T, r_N=s.r_N) for s in st]
    assert check_block_path(st_m, 0.08, 0.04) == []
    bad = st + [EquilibriumState(index=5, load={"u_x": -0.5, "u_y": -0.5}, u_T=np.zeros(3),
                                 u_N=np.array([0.0, 0.6, 0.0]), r_T=np.zeros(3), r_N=-np.ones(3))]
    w = check_block_path(bad, 80.0, 40.0)
    assert len(w) == 1 and "penetration" in w[0] and "state 5" in w[0] and "1.5 %" in w[0]


def test_mount_point_target_is_refused_before_the_work(tmp_path):
    with tmpfs(tmp_path / "mnt", "8m") as mnt:
        scene = tmp_path / "s.yaml"
        scene.write_text(TP)
        line = _one_error_line(run_cli_here("run", str(scene), "-o", str(mnt), "-q", "--overwrite"))
        assert "mount point" in line and os.listdir(mnt) == []
        _no_litter(tmp_path)


def test_someone_elses_empty_folder_in_a_sticky_folder_is_refused(tmp_path, monkeypatch):
    """As on /tmp: the rename over another user's folder would fail at the end, so it is refused first."""
    import app.io.folder as folder_mod
    parent = tmp_path / "shared"
    parent.mkdir()
    os.chmod(parent, 0o1777)
    (parent / "out").mkdir()                             # owned by root, we pretend to be uid 4242
    monkeypatch.setattr(folder_mod.os, "geteuid", lambda: 4242)
    problem = folder_mod.ResultsFolder(parent / "out", overwrite=True).check()
    assert problem and "belongs to another user" in problem
    assert sorted(os.listdir(parent)) == ["out"]


@pytest.mark.parametrize("existing", ["staging", "probe"])
def test_failed_staging_probe_removes_only_what_this_run_created(tmp_path, existing):
    """The pre-flight's staging probe cleans up after a failure, but never a path that was there
    before (a leftover or a user's folder with the same name)."""
    from app.io.folder import ResultsFolder
    rf = ResultsFolder(tmp_path / "out", overwrite=False)
    path = rf.staging if existing == "staging" else rf.staging.with_name(rf.staging.name + "-probe")
    (path / "sub").mkdir(parents=True)
    (path / "sub" / "keep.txt").write_text("not the app's")
    before = _snapshot(tmp_path)
    problem = rf.check()
    assert problem is not None and "cannot write the output folder" in problem
    assert _snapshot(tmp_path) == before          # nothing removed, nothing left behind
    rf.lock.release()


def test_render_refuses_a_folder_the_app_did_not_write(tmp_path):
    """`render` replaces pictures: it refuses a folder without the app's marker (user files stay)."""
    mine = tmp_path / "mine"
    (mine / "plots").mkdir(parents=True)
    (mine / "plots" / "figure.png").write_bytes(b"user picture")
    (mine / "results.json").write_text(json.dumps({"scene_config": {"outputs": {"plots": True}}, "states": []}))
    before = _snapshot(mine)
    line = _one_error_line(run_cli_here("render", str(mine)))
    assert "not a results folder written by this app" in line
    assert _snapshot(mine) == before
