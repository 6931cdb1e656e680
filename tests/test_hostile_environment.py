"""Odd environments (issue 32): hard resource limits of a batch job, unusable cache and home
folders, output paths with a newline, a Ctrl-C of an mpirun sweep, a full disk under the
drawing processes. Each ends in a result or in one ``error:`` line, never a traceback.
"""
from __future__ import annotations

import os
import pathlib
import resource
import subprocess

import pytest
from conftest import PY, ROOT, one_error_line

GEO_SCENE = """\
name: g
system:
  type: gmsh
  file: block.geo
  contact: AB
  prescribed: {CD: xy}
  material: {E: 5.0, nu: 0.48, density: 1.2e-9}
  thickness: 9.6
  obstacle: {point: [0, 0], normal: [0, -1]}
  program:
    - {name: press, steps: 10, displacement: {CD: {translation: [0, -1]}}, until: {normal_force: 55}}
    - {name: drag, steps: 10, displacement: {CD: {translation: [-0.5, 0]}}}
mu: 1.1
analyses: [mceip_mu]
"""
BLOCK = """\
name: blk
system: {type: block, nx: 6, ny: 3}
mu: 1.1
loading: {normal_force: 55.0, normal_steps: 3, tangential_step: 0.25, tangential_max: 1.5}
analyses: [mceip_mu]
"""


def _env(**extra: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    env.update(extra)
    return env


def _geo_scene(folder: pathlib.Path) -> pathlib.Path:
    """The shipped .geo block, 10 x 5 cells, with a short loading program."""
    geo = (ROOT / "app" / "scenes" / "gmsh" / "block.geo").read_text()
    (folder / "block.geo").write_text(geo.replace("nx = 20; ny = 10;", "nx = 10; ny = 5;"))
    scene = folder / "g.yaml"
    scene.write_text(GEO_SCENE)
    return scene


# ---------------------------------------------------------------------------------------------
# Hard resource limits (ulimit -v, ulimit -f in a batch job)


def test_child_limits_never_exceed_the_inherited_hard_limits():
    from app.common.rlimits import INFINITY, Limit, lowered, within_inherited
    assert lowered(Limit(10, 10), Limit(INFINITY, INFINITY)) == Limit(10, 10)
    assert lowered(Limit(10, 10), Limit(4, 6)) == Limit(4, 6)              # the soft limit is kept too
    assert lowered(Limit(10, 10), Limit(INFINITY, 6)) == Limit(6, 6)
    assert lowered(Limit(5, 6), Limit(8, 7)) == Limit(5, 6)
    assert lowered(Limit(INFINITY, INFINITY), Limit(3, 9)) == Limit(3, 9)
    assert lowered(Limit(0, 0), Limit(4, 4)) == Limit(0, 0)
    inherited = {resource.RLIMIT_AS: (8 << 30, 8 << 30), resource.RLIMIT_CPU: (INFINITY, INFINITY),
                 resource.RLIMIT_FSIZE: (INFINITY, 1 << 20)}
    got, notes = within_inherited({resource.RLIMIT_AS: Limit(20 << 30, 20 << 30),
                                   resource.RLIMIT_CPU: Limit(62, 63),
                                   resource.RLIMIT_FSIZE: Limit(64 << 20, 64 << 20)}, inherited.__getitem__)
    assert got == {resource.RLIMIT_AS: Limit(8 << 30, 8 << 30), resource.RLIMIT_CPU: Limit(62, 63),
                   resource.RLIMIT_FSIZE: Limit(1 << 20, 1 << 20)}
    assert len(notes) == 2 and "ulimit -v" in notes[0] and "ulimit -f" in notes[1], notes


def test_sandbox_limits_within_the_inherited_ones():
    """The Gmsh child's limits under a batch job's hard ``ulimit -v`` and ``ulimit -f``."""
    from app.common.rlimits import INFINITY, Limit
    from app.systems.gmsh.sandbox import BASE_ADDRESS_SPACE, SandboxLimits, child_limits
    lim = SandboxLimits(seconds=60.0, memory_bytes=1 << 34, max_nodes=10, max_elements=10, max_dofs=20)
    free = {r: (INFINITY, INFINITY) for r in (resource.RLIMIT_AS, resource.RLIMIT_FSIZE, resource.RLIMIT_CPU,
                                               resource.RLIMIT_CORE)}
    got, notes = child_limits(lim, 64 << 20, free.__getitem__)
    assert got[resource.RLIMIT_AS] == Limit((1 << 34) + BASE_ADDRESS_SPACE, (1 << 34) + BASE_ADDRESS_SPACE)
    assert got[resource.RLIMIT_FSIZE] == Limit(64 << 20, 64 << 20) and got[resource.RLIMIT_CPU] == Limit(62, 63)
    assert got[resource.RLIMIT_CORE] == Limit(0, 0) and notes == []
    batch = dict(free)
    batch[resource.RLIMIT_AS] = (8_000_000 << 10, 8_000_000 << 10)
    batch[resource.RLIMIT_FSIZE] = (INFINITY, 1 << 20)
    got, notes = child_limits(lim, 64 << 20, batch.__getitem__)
    assert got[resource.RLIMIT_AS] == Limit(8_000_000 << 10, 8_000_000 << 10)
    assert got[resource.RLIMIT_FSIZE] == Limit(1 << 20, 1 << 20)
    assert len(notes) == 2, notes


def test_geo_scene_runs_under_hard_batch_limits(tmp_path):
    """``ulimit -v`` and ``ulimit -f`` set hard limits, as a batch job's script does: the Gmsh
    sandbox used to ask for more than them and crash in ``preexec_fn``. Now the .geo scene runs,
    and one warning says the inherited address-space limit is lower than the sandbox's."""
    scene = _geo_scene(tmp_path)
    cmd = f'ulimit -v 8000000 && ulimit -f 10000000 && exec "{PY}" -m app run "{scene}" -o "{tmp_path / "out"}" -q'
    p = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=600)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "out" / "results.json").is_file()
    lines = p.stderr.splitlines()
    assert len(lines) == 1 and "ulimit -v" in lines[0] and "Traceback" not in p.stderr, p.stderr


# ---------------------------------------------------------------------------------------------
# Cache folders: XDG_CACHE_HOME a file, HOME not writable


def _one_warning_then_results(p: subprocess.CompletedProcess, out: pathlib.Path, variable: str) -> None:
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr
    lines = p.stderr.splitlines()
    assert len(lines) == 1 and variable in lines[0] and "contact-divergence-cache-" in lines[0], p.stderr
    assert {"results.json", "plots", "screenshots"} <= {f.name for f in out.iterdir()}
    assert list((out / "plots").glob("*.png")) and list((out / "screenshots").glob("*.png"))


PICTURES = "outputs: {plots: true, screenshots: true}\n"


def test_xdg_cache_home_a_file_falls_back_to_a_working_cache(tmp_path):
    """The JIT cache (``$XDG_CACHE_HOME/fenics``) and matplotlib's folder cannot be created under
    a file: the run used to end in a traceback from FFCx. The caches go to this user's folder in
    the temporary folder, with one warning naming the variable."""
    (tmp_path / "cache").write_text("a file")
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK + PICTURES)
    (tmp_path / "tmp").mkdir()
    p = subprocess.run([PY, "-m", "app", "run", str(scene), "-o", str(tmp_path / "out"), "-q"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=600,
                       env=_env(XDG_CACHE_HOME=str(tmp_path / "cache"), TMPDIR=str(tmp_path / "tmp")))
    _one_warning_then_results(p, tmp_path / "out", "XDG_CACHE_HOME")
    assert list((tmp_path / "tmp").glob("contact-divergence-cache-*/fenics/*.so"))


def test_read_only_home_falls_back_to_a_working_cache(tmp_path):
    """HOME on a read-only file system (a service account's, a batch job's) and no XDG_CACHE_HOME:
    the run works, with one warning (matplotlib's own two lines are not printed)."""
    from conftest import tmpfs
    with tmpfs(tmp_path / "home", "1m") as home:
        subprocess.run(["mount", "-o", "remount,ro", str(home)], check=True)
        scene = tmp_path / "s.yaml"
        scene.write_text(BLOCK + PICTURES)
        (tmp_path / "tmp").mkdir()
        env = _env(HOME=str(home), TMPDIR=str(tmp_path / "tmp"))
        for variable in ("XDG_CACHE_HOME", "XDG_CONFIG_HOME", "MPLCONFIGDIR"):
            env.pop(variable, None)
        p = subprocess.run([PY, "-m", "app", "run", str(scene), "-o", str(tmp_path / "out"), "-q"],
                           capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
        _one_warning_then_results(p, tmp_path / "out", "HOME")
        assert list((tmp_path / "tmp").glob("contact-divergence-cache-*/matplotlib"))


def test_home_a_file_and_fifo_settings_files_in_the_study_folder(tmp_path):
    """DOLFINx and FFCx read ``*_parameters.json`` from the current folder and from ``~/.config``
    (catching only FileNotFoundError): FIFOs of those names in a study folder received from
    someone hung the run, and a HOME that is a file ended it with a traceback. The app gives
    every parameter itself and reads neither."""
    study = tmp_path / "study"
    study.mkdir()
    for name in ("ffcx_parameters.json", "dolfinx_jit_parameters.json"):
        os.mkfifo(study / name)
    (study / "s.yaml").write_text(BLOCK + PICTURES)
    (tmp_path / "tmp").mkdir()
    (tmp_path / "home").write_text("a file, not a folder")
    env = _env(HOME=str(tmp_path / "home"), TMPDIR=str(tmp_path / "tmp"))
    for variable in ("XDG_CACHE_HOME", "XDG_CONFIG_HOME", "MPLCONFIGDIR"):
        env.pop(variable, None)
    p = subprocess.run([PY, "-m", "app", "run", "s.yaml", "-o", str(tmp_path / "out"), "-q"], capture_output=True,
                       text=True, cwd=study, env=env, timeout=600)
    _one_warning_then_results(p, tmp_path / "out", "HOME")


def test_no_writable_cache_anywhere_is_one_line(tmp_path, monkeypatch):
    """Neither the user's cache folder nor the temporary folder can be written: one line naming
    XDG_CACHE_HOME, exit status 2 (the JIT cache is asked for before any form is compiled)."""
    import tempfile

    from conftest import run_cli_here
    blocker = tmp_path / "file"
    blocker.write_text("a file")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    monkeypatch.setenv("TMPDIR", str(blocker / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", str(blocker / "tmp"))
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK)
    line = one_error_line(run_cli_here("run", str(scene), "-o", str(tmp_path / "out"), "-q"))
    assert "XDG_CACHE_HOME" in line and str(blocker) in line, line
    assert not (tmp_path / "out").exists()


def test_mesh_cache_falls_back_when_xdg_cache_home_is_a_file(tmp_path, monkeypatch):
    """The install folder's meshes/ and $XDG_CACHE_HOME cannot be written: the block mesh is
    cached in this user's folder in the temporary folder; with no folder at all, one line."""
    import tempfile

    from mpi4py import MPI

    import app.systems.block.mesh as bm
    from app.common.cache import CacheUnusable
    blocker = tmp_path / "file"
    blocker.write_text("a file")
    monkeypatch.setattr(bm, "DEFAULT_CACHE_DIR", blocker / "meshes")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    mesh, _ = bm.block_mesh(MPI.COMM_WORLD, 80.0, 40.0, 3, 2, "right")
    assert mesh.topology.index_map(2).size_global == 12
    name = bm.mesh_file_name(80.0, 40.0, 3, 2, "right", None)
    assert (tmp_path / "tmp" / f"contact-divergence-cache-{os.getuid()}" / "contact-divergence" / "meshes"
            / name).is_file()
    monkeypatch.setenv("TMPDIR", str(blocker / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", str(blocker / "tmp"))
    with pytest.raises(CacheUnusable, match="XDG_CACHE_HOME"):
        bm.block_mesh(MPI.COMM_WORLD, 80.0, 40.0, 3, 2, "right")


# ---------------------------------------------------------------------------------------------
# The drawing processes: any output path, no traceback, a full disk is the run's full disk


def test_output_path_with_a_newline_gets_its_pictures(tmp_path):
    """The job file's name used to be handed to the drawing processes as a line: a newline in the
    output folder's name cut it, and the pictures went missing with exit status 0."""
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK + PICTURES)
    out = tmp_path / "out\nx"
    p = subprocess.run([PY, "-m", "app", "run", str(scene), "-o", str(out), "-q"], capture_output=True, text=True,
                       cwd=tmp_path, env=_env(), timeout=600)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert list((out / "plots").glob("*.png")) and list((out / "screenshots").glob("*.png"))
    import json
    res = json.loads((out / "results.json").read_text())
    assert not [n for n in res["outputs"]["notes"] if "failed" in n], res["outputs"]["notes"]


def _plots_job(tmp_path: pathlib.Path, plots_dir: pathlib.Path) -> pathlib.Path:
    """A drawing job of the plots of a small two-particle study, drawing into ``plots_dir``."""
    import json

    from conftest import run_cli_here
    scene = tmp_path / "tp.yaml"
    scene.write_text("name: tp\nsystem: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}\n"
                     "mu: 2.5\nanalyses: [mceip_mu]\noutputs: {plots: true}\n")
    assert run_cli_here("run", str(scene), "-o", str(tmp_path / "tp"), "-q").returncode == 0
    res = json.loads((tmp_path / "tp" / "results.json").read_text())
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"results": res, "pictured": res["outputs"]["pictured_states"],
                               "plots_dir": str(plots_dir)}))
    return job


def test_a_failing_drawing_process_is_a_note_and_one_warning(tmp_path, capfd):
    """A drawing child that fails prints no traceback: the parent gets its one-line reason as a
    note and logs it as one warning."""
    from app.plot.worker import Worker
    files, notes, seconds = Worker("plots").submit(tmp_path / "no such job.json").wait()
    err = capfd.readouterr().err
    assert files == [] and seconds is None and len(notes) == 1, notes
    assert "plots failed: FileNotFoundError" in notes[0] and "no such job.json" in notes[0], notes
    assert "Traceback" not in err and err.count("\n") <= 1, err


def test_full_disk_in_a_drawing_process_is_the_runs_full_disk(tmp_path, capfd):
    """The plots child writes onto a full file system: no traceback from it, and the parent gets
    the child's ENOSPC as an OSError, which ends a run with 'no space left' (exit status 4)."""
    import errno

    from conftest import fill_disk, tmpfs

    from app.plot.worker import Worker
    job = _plots_job(tmp_path, tmp_path / "mnt" / "plots")
    with tmpfs(tmp_path / "mnt", "1m") as mnt:
        fill_disk(mnt)
        capfd.readouterr()
        with pytest.raises(OSError) as info:
            Worker("plots").submit(job).wait()
        err = capfd.readouterr().err
    assert info.value.errno == errno.ENOSPC, info.value
    assert err == "", err


# ---------------------------------------------------------------------------------------------
# Ctrl-C of a sweep


SWEEP = """\
name: sw
system: {type: block, nx: 10, ny: 5}
mu: 1.1
loading: {normal_force: 55.0, normal_steps: 3, tangential_step: 0.01, tangential_max: 1.5}
analyses: [mceip_mu]
sweep: {parameters: {mu: [%s]}}
""" % ", ".join(f"{0.5 + 0.02 * i:.2f}" for i in range(60))


def _interrupt_sweep(tmp_path: pathlib.Path, ranks: int) -> tuple[subprocess.Popen, str, pathlib.Path]:
    """A sweep started as from a terminal (``mpirun -n ranks`` when ranks > 1), sent SIGINT once
    it has completed a few cases (so every rank is past its imports); (process, stderr, folder)."""
    import signal
    import time
    scene = tmp_path / "sw.yaml"
    scene.write_text(SWEEP)
    out = tmp_path / "out"
    cmd = [PY, "-m", "app", "run", str(scene), "-o", str(out), "-q"]
    if ranks > 1:
        cmd = ["mpirun", "--oversubscribe", "-n", str(ranks), *cmd]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 300
        while len(list(out.glob("cases/*/results.json"))) < 2 * ranks:
            assert proc.poll() is None and time.monotonic() < deadline, "the sweep ended before it was interrupted"
            time.sleep(0.01)
        os.killpg(proc.pid, signal.SIGINT)          # a Ctrl-C: the terminal signals the foreground group
        err = proc.communicate(timeout=120)[1].decode()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.poll() is not None and len(list(out.glob("cases/*/results.json"))) < 60, "the sweep was not stopped"
    return proc, err, out


def _stopped_sweep_left_its_complete_cases(err: str, out: pathlib.Path, signal_name: str) -> None:
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith(f"error: interrupted by {signal_name}") and "the sweep stopped" in err, err
    assert str(out) in err
    cases = sorted(p.name for p in (out / "cases").iterdir())
    assert not [c for c in cases if ".partial-" in c], cases
    assert all((out / "cases" / c / "results.json").is_file() for c in cases), cases
    assert not list(out.parent.glob(".out.lock"))


def test_ctrl_c_of_a_sweep_is_one_line_and_130(tmp_path):
    proc, err, out = _interrupt_sweep(tmp_path, 1)
    assert proc.returncode == 130, err
    _stopped_sweep_left_its_complete_cases(err, out, "SIGINT")


@pytest.mark.mpi
def test_ctrl_c_of_an_mpirun_sweep_is_one_line(tmp_path):
    """A Ctrl-C reaches mpirun (the ranks are in process groups of their own), which sends SIGTERM
    to every rank and exits 1 whatever the ranks do (Open MPI 4: it neither forwards SIGINT nor
    passes the ranks' status on). Every rank removes its unfinished case and ends; rank 0 prints
    the one line. It used to print nothing."""
    proc, err, out = _interrupt_sweep(tmp_path, 2)
    assert proc.returncode == 1, err
    _stopped_sweep_left_its_complete_cases(err, out, "SIGTERM")


STUDY_TO_STOP = """\
name: stop-me
system: {type: block, nx: 180, ny: 90}
mu: 1.1
analyses: [necessary, mceip_lambda2]
"""


@pytest.mark.mpi
def test_ctrl_c_of_an_mpirun_study_inside_rank_zeros_work_is_one_line(tmp_path):
    """A Ctrl-C while rank 0 computes the values of (19) and MCEIP-lambda^2 on the contact DOFs
    (65k DOFs) and rank 1 sleeps until it has them (app/common/waiting.py): the one line, no
    traceback and no MPI_Abort banner (rank 1 takes the SIGTERM at once, in Python, and waits for
    rank 0 to clean up and end the job), nothing left behind, the job over within seconds."""
    import signal
    import time
    scene = tmp_path / "stop.yaml"
    scene.write_text(STUDY_TO_STOP)
    out = tmp_path / "out"
    proc = subprocess.Popen(["mpirun", "--oversubscribe", "-n", "2", PY, "-m", "app", "run", str(scene), "-o", str(out)],
                            cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        lines = []
        for line in proc.stderr:              # progress lines, every 5 s: the first of the analyses
            lines.append(line)
            if line.startswith("analyses:") and ("necessary" in line or "MCEIP-lambda" in line):
                break
        assert proc.poll() is None, "".join(lines)
        os.killpg(proc.pid, signal.SIGINT)
        t0 = time.monotonic()
        rest = proc.communicate(timeout=120)[1]
        stopped = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    after = [x for x in rest.splitlines() if not x.startswith(("analyses:", "loading:"))]
    assert after == ["error: interrupted by SIGTERM; the run stopped and wrote no results"], rest
    assert not out.exists() and not list(tmp_path.glob(".out*")), sorted(p.name for p in tmp_path.iterdir())
    assert stopped < 30, stopped


def test_disk_full_while_the_plots_are_drawn(tmp_path):
    """The file system fills up once the plots child has begun writing (its plots/ folder exists):
    one 'no space left' line, exit status 4, no traceback from the child, nothing left behind."""
    import time

    from conftest import fill_disk, tmpfs
    scene = tmp_path / "s.yaml"
    scene.write_text(BLOCK + "outputs: {plots: true, report: true}\n")
    with tmpfs(tmp_path / "mnt", "64m") as mnt:
        proc = subprocess.Popen([PY, "-m", "app", "run", str(scene), "-o", str(mnt / "out"), "-q"], cwd=tmp_path,
                                env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 300
            while not list(mnt.glob(".out.partial-*/plots")):
                assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
                time.sleep(0.001)
            fill_disk(mnt)
            stdout, stderr = proc.communicate(timeout=300)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        (mnt / "fill").unlink()
        assert proc.returncode == 4, (stdout, stderr)
        assert len(stderr.splitlines()) == 1 and "no space left" in stderr and "Traceback" not in stderr, stderr
        assert os.listdir(mnt) == []


def test_a_petscrc_in_the_study_folder_injects_no_option(tmp_path):
    """PETSc reads ``.petscrc`` and ``petscrc`` from the working folder: one in a study folder received
    from someone wrote a file with ``-mat_view ascii:FILE``. ``python -m app`` starts PETSc with
    ``-skip_petscrc``; ``PETSC_OPTIONS`` (the user's own) still reaches PETSc."""
    study = tmp_path / "study"
    study.mkdir()
    for name in (".petscrc", "petscrc"):
        (study / name).write_text(f"-mat_view ascii:{tmp_path / name}.txt\n-options_left\n")
    (study / "s.yaml").write_text(BLOCK)
    p = subprocess.run([PY, "-m", "app", "run", "s.yaml", "-o", str(tmp_path / "out"), "-q"], capture_output=True,
                       text=True, cwd=study, env=_env(), timeout=600)
    assert p.returncode == 0 and "Option left" not in p.stdout + p.stderr, p.stdout + p.stderr
    assert not list(tmp_path.glob("*.txt"))
    p = subprocess.run([PY, "-m", "app", "run", "s.yaml", "-o", str(tmp_path / "out2"), "-q"], capture_output=True,
                       text=True, cwd=study, env=_env(PETSC_OPTIONS="-options_left"), timeout=600)
    assert p.returncode == 0 and "PETSc Option Table" in p.stdout + p.stderr, p.stdout + p.stderr


def test_a_file_size_limit_reached_while_writing_is_one_line(tmp_path):
    """A batch job's ``ulimit -f``: Python ignores SIGXFSZ, so the write that passes the limit fails
    with EFBIG, which ended the run in a traceback from the ParaView writer. Now it is one line
    naming the limit, exit status 4, and the staging folder is removed."""
    scene = tmp_path / "s.yaml"
    scene.write_text("name: fsz\nsystem: {type: block, nx: 40, ny: 20}\nmu: 1.1\nanalyses: [mceip_mu]\n"
                     "outputs: {paraview: true}\n")
    limit = 8 * 2**20                  # MPI's start-up needs a few MiB of files; the ParaView series more

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    p = subprocess.run([PY, "-m", "app", "run", str(scene), "-o", str(tmp_path / "out"), "-q"], capture_output=True,
                       text=True, cwd=tmp_path, env=_env(), timeout=600, preexec_fn=cap)
    line = one_error_line(p, 4)
    assert "file-size limit" in line and "ulimit -f" in line and "8 MiB" in line, line
    assert sorted(os.listdir(tmp_path)) == ["s.yaml"]
