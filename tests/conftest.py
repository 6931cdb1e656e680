import atexit
import contextlib
import errno
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import pytest
from mpi4py import MPI

# MPI_Init of this process (one rank, a singleton) exports the variables of its own PMIx server.
# A child ``mpirun`` that inherits them takes itself for a rank of that singleton and exits 1
# without a word, so they are removed from the environment the tests' children get (under
# pytest-xdist they are also in ``os.environ``).
if MPI.COMM_WORLD.size == 1:
    for _key in [k for k in os.environ if k.startswith(("PMIX_", "ORTE_", "OMPI_MCA_orte_", "OMPI_APP_CTX_"))
                 or k in ("OMPI_MCA_ess", "OMPI_MCA_pmix")]:
        del os.environ[_key]

# the ranks of the tests' own mpirun children yield their core while they wait (as app/cli/main.py
# sets for `python -m app`): the suite runs on every core (pytest-xdist), and a spinning rank
# can slow a neighbouring test's rank a hundredfold
os.environ.setdefault("OMPI_MCA_mpi_yield_when_idle", "1")

# Open MPI jobs started at the same time by the same user share /tmp/ompi.<host>.<uid> and race in
# its creation and clean-up (open-mpi/ompi#8510); twice in about ten suite runs a child of a test
# exited 1 without a word while the other worker ran an mpirun. Each worker's children get a
# session directory tree of their own (removed when the worker ends).
_OMPI_TMP = tempfile.mkdtemp(prefix="cd-tests-ompi-")
os.environ.setdefault("OMPI_MCA_orte_tmpdir_base", _OMPI_TMP)
atexit.register(shutil.rmtree, _OMPI_TMP, True)

ROOT = pathlib.Path(__file__).resolve().parents[1]
PY = sys.executable


def pytest_sessionstart(session):
    """``pytest -q`` (as ``make test``) hides the report header: print the versions anyway."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None and session.config.get_verbosity() < 0:
        for line in pytest_report_header(session.config):
            reporter.write_line(line)



def pytest_report_header(config):
    """The session's first lines: the installed version of every package of requirements.lock
    (a mismatch is marked and fails tests/test_environment.py) and of Debian's compiled stack."""
    import importlib.metadata as md
    import re
    text = (ROOT / "requirements.lock").read_text(encoding="utf-8")
    shown = []
    for name, want in re.findall(r"^([A-Za-z0-9_.\-]+)==([^\s\\;]+)", text, re.M):
        try:
            have = md.version(name)
        except md.PackageNotFoundError:
            have = "missing"
        shown.append(name + "==" + have + ("" if have == want else f" (locked {want})"))
    debian = []
    for name in ("numpy", "scipy", "mpi4py", "petsc4py", "slepc4py", "fenics-dolfinx"):
        try:
            debian.append(f"{name}=={md.version(name)}")
        except md.PackageNotFoundError:
            pass
    return [f"locked packages ({len(shown)}): " + ", ".join(shown),
            "Debian packages: " + ", ".join(debian)]


def run_scene(data: dict) -> dict:
    """Run a scene given as a dict in this process; returns its results as a user reads them in
    results.json (``StudyResult.to_dict``: non-finite numbers as floats)."""
    from app.scene.schema import parse_scene
    from app.study.run import study
    return study(parse_scene(data), MPI.COMM_WORLD).to_dict()


def minimal_study(states: list[dict], **fields):
    """A typed study (app/io/result.py) around hand-written ``states``, the keys every run writes
    filled with neutral values: a state's missing ``load``, ``nodes``, ``analyses`` and
    classification counts, a solution's missing ``x_Ts`` and ``pattern``."""
    from app.io.result import StudyResult

    def solution(d: dict) -> dict:
        return {"x_Ts": [1.0], "pattern": ["slip"], **d}

    def analyses(a: dict) -> dict:
        out = {}
        for name, block in a.items():
            block = dict(block)
            for key in ("solutions", "modes"):
                if key in block:
                    block[key] = [solution(d) for d in block[key]]
            out[name] = block
        return out

    typed = [{"load": {}, "nodes": [], "analyses_shared_with": None, **st,
              "classification": {"free": 0, "zero": 0, "stick": 0, "slip": 0, **st.get("classification", {})},
              "analyses": analyses(st.get("analyses", {}))} for st in states]
    return StudyResult.from_dict({
        "scene": "test", "units": {"length": "mm", "force": "N", "lambda2": "1/s^2", "mu": "1"}, "system": "test",
        "mu": 1.0, "analyses_requested": [], "path": {"end": "test"}, "distinct_classifications": len(states),
        "stages": [], "failures": [], "warnings": [], "mpi_ranks": 1, "wall_seconds": 0.0, "scene_config": {},
        **fields, "states": typed})


def run_cli(*args: str, ranks: int = 1, timeout: float = 600, cwd=None) -> subprocess.CompletedProcess:
    """Run ``python -m app ARGS`` (under mpirun when ranks > 1)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=str(ROOT))
    cmd = [PY, "-m", "app", *args]
    if ranks > 1:
        cmd = ["mpirun", "--oversubscribe", "-n", str(ranks), *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd or ROOT)



def run_cli_here(*args: str, cwd=None) -> subprocess.CompletedProcess:
    """``python -m app ARGS`` in this process: :func:`app.cli.main.main` with stdout and stderr
    captured, for the CLI's user-error paths, where a new interpreter (about 1 s of DOLFINx
    imports) adds nothing. The root logger's handlers and level, and the SIGTERM and SIGINT
    handlers a run installs, are restored afterwards."""
    import contextlib
    import io
    import logging
    import signal

    from app.cli.main import main
    out, err = io.StringIO(), io.StringIO()
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    signals = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), contextlib.chdir(cwd or ROOT):
            try:
                code = main(list(args))
            except SystemExit as exc:     # argparse's usage errors
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        root.handlers[:] = handlers
        root.setLevel(level)
        for sig, handler in signals.items():
            signal.signal(sig, handler)
    return subprocess.CompletedProcess([PY, "-m", "app", *args], code, out.getvalue(), err.getvalue())


def results_on_ranks(scene, outdir, ranks=(1, 2), cwd=None) -> dict:
    """results.json of ``python -m app run SCENE`` on each number of ``ranks`` (output folders
    ``outdir/o<ranks>``), every run asserted to succeed. The one-rank run is :func:`run_cli_here`
    (the same ``main`` on a singleton COMM_WORLD, without a new interpreter); the others run
    under ``mpirun``."""
    import json
    out = {}
    for n in ranks:
        args = ("run", str(scene), "-o", str(outdir / f"o{n}"), "-q")
        p = run_cli_here(*args, cwd=cwd) if n == 1 else run_cli(*args, ranks=n, cwd=cwd)
        assert p.returncode == 0, p.stderr
        out[n] = json.loads((outdir / f"o{n}" / "results.json").read_text())
    return out

def one_error_line(proc: subprocess.CompletedProcess, code: int = 2) -> str:
    """The single ``error:`` line of a failed CLI run with exit status ``code`` (and no traceback)."""
    out = proc.stdout + proc.stderr
    assert "Traceback" not in out, out
    assert proc.returncode == code, (proc.returncode, out)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    return lines[0]


@pytest.fixture
def scene_file(tmp_path):
    def write(text: str, name: str = "scene.yaml") -> pathlib.Path:
        p = tmp_path / name
        p.write_text(text)
        return p
    return write


@contextlib.contextmanager
def tmpfs(path: pathlib.Path, size: str):
    """A tmpfs of ``size`` mounted at ``path`` (created) for the block, unmounted after it; the test
    is skipped where tmpfs cannot be mounted."""
    path.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], capture_output=True)


def fill_disk(folder: pathlib.Path) -> pathlib.Path:
    """Write zeros to ``folder/fill`` until the file system is full (ENOSPC); returns the file."""
    path = folder / "fill"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT)
    try:
        while True:
            os.write(fd, b"\0" * 65536)
    except OSError as err:
        assert err.errno == errno.ENOSPC
    finally:
        os.close(fd)
    return path


@pytest.fixture(autouse=True)
def _no_interrupt_left_behind():
    """A test that exercises the CLI's signal handler in this process must not leave a received
    signal behind: the next study's checkpoints would raise it (app/common/interrupt.py)."""
    yield
    from app.common import interrupt
    left = list(interrupt.RECEIVED)
    interrupt.clear()
    assert not left, f"a test left the received signal(s) {left} behind"


@pytest.fixture(autouse=True)
def _logging_as_it_was():
    """The root logger's handlers and level, and the ``app`` logger's level, as before the test: a
    test that runs the CLI's ``main`` directly (its ``setup_logging`` adds a handler on the
    ``sys.stderr`` of that moment) or that first imports FFCx (``logging.basicConfig()`` on import)
    under ``capsys`` would leave a handler writing to a stream closed after it, and any later test
    that logs would print "--- Logging error ---" (seen in a fresh clone's CI run)."""
    import logging
    root, app_log = logging.getLogger(), logging.getLogger("app")
    handlers, level, app_level = root.handlers[:], root.level, app_log.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)
    app_log.setLevel(app_level)
