"""Progress of the MCEIP-mu stage (app/common/progress.py ``Progress.tasks``, hooked in app/study/scheduler.py).

A study whose per-classification MCEIP-mu is made slow (it sleeps) must still print a progress
line at least every 5 s, naming the classifications done, the s running now, the last result and
the time left; the estimate itself is checked on its own.
"""
from __future__ import annotations

import io
import time
from types import SimpleNamespace

import pytest
import yaml

import app.study.scheduler as distributed
from app.common.progress import Progress, time_left
from app.scene.schema import default_scene_path, parse_scene
from app.study.run import study


class _Recorder(io.StringIO):
    """A non-terminal stream that records when each line was written."""

    def __init__(self):
        super().__init__()
        self.lines: list[tuple[float, str]] = []

    def write(self, text: str) -> int:
        for line in text.splitlines():
            self.lines.append((time.perf_counter(), line))
        return len(text)

    def isatty(self) -> bool:
        return False


def test_time_left_from_the_rate_so_far():
    assert time_left(10.0, 0.0, 100.0) is None                  # nothing done: no estimate
    assert time_left(10.0, 25.0, 100.0) == pytest.approx(30.0)  # 25 cost units in 10 s, 75 left
    assert time_left(10.0, 100.0, 100.0) == 0.0


def test_a_long_task_repeats_its_line():
    rec = _Recorder()
    with Progress(enabled=True, comm=SimpleNamespace(rank=0), stream=rec, interval=0.3).tasks(
            3, "work", unit="job", total_cost=30.0) as tasks:
        tasks.start("job A")
        time.sleep(1.2)
        tasks.finish("job A ok", 10.0)
    texts = [t for _, t in rec.lines]
    running = [t for t in texts if "now job A" in t]
    assert len(running) >= 2, texts                               # written while the job ran
    assert running[0].startswith("work: 0/3 jobs (0%)")
    assert texts[-1].startswith("work: 1/3 jobs") and texts[-1].endswith(", done")
    assert "last job A ok" in texts[-1]


def test_quiet_progress_writes_nothing():
    rec = _Recorder()
    with Progress(enabled=False, comm=SimpleNamespace(rank=0), stream=rec).tasks(2, "work") as tasks:
        tasks.start("a")
        tasks.finish("a", 1.0)
    assert rec.lines == []


@pytest.mark.slow
def test_slow_mceip_mu_prints_a_line_at_least_every_5_s(monkeypatch):
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    data.update(analyses=["mceip_mu"])
    data["loading"].update(tangential_max=3.0)
    scene = parse_scene(data)
    real, calls = distributed.state_mceip_mu, []

    def slow(*args, **kwargs):
        if kwargs.get("replicated", True) is False:      # the MCEIP-mu stage (not the s = 0 states)
            calls.append(1)
            if len(calls) <= 2:
                time.sleep(6.5)                  # each longer than the 5 s interval
        return real(*args, **kwargs)

    monkeypatch.setattr(distributed, "state_mceip_mu", slow)
    rec = _Recorder()
    t0 = time.perf_counter()
    from mpi4py import MPI
    res = study(scene, MPI.COMM_WORLD, Progress(enabled=True, comm=SimpleNamespace(rank=0), stream=rec)).to_dict()
    total = res["distinct_classifications"]
    lines = [(t, x) for t, x in rec.lines if x.startswith("MCEIP-mu:")]
    assert len(calls) >= 3 and lines
    stamps = [t for t, _ in lines]
    first = min(t for t, x in rec.lines if x.startswith("analyses:"))   # the stage starts after the analyses bar
    gaps = [b - a for a, b in zip([first] + stamps, stamps)]
    assert max(gaps) <= 5.0 + 1.0, gaps              # the thread looks every second
    assert stamps[-1] - t0 >= 13.0                   # the slow calls did run inside the stage
    running = [x for _, x in lines if "now s = " in x]
    assert running, [x for _, x in lines]
    assert any("last s = " in x and ("proven" in x) for _, x in lines)
    assert any("left (estimate)" in x for _, x in lines)
    n_deferred = len(calls)
    assert lines[-1][1].startswith(f"MCEIP-mu: {n_deferred}/{n_deferred} classifications (100%)")
    assert lines[-1][1].endswith(", done") and n_deferred <= total


def test_a_long_task_shows_what_it_is_doing():
    """The line written while one task runs carries its live detail (the prover's phase and tree)."""
    rec = _Recorder()
    state = {"text": "onset proof, 12 tree nodes, at mu = 3.5"}
    with Progress(enabled=True, comm=SimpleNamespace(rank=0), stream=rec, interval=0.3).tasks(
            1, "MCEIP-mu", unit="classification", total_cost=1.0) as tasks:
        tasks.start("s = 574", detail=lambda: state["text"])
        time.sleep(0.8)
        tasks.finish("s = 574 proven", 1.0)
    running = [t for _, t in rec.lines if "now s = 574" in t]
    assert running and all("onset proof, 12 tree nodes, at mu = 3.5" in t for t in running), running


def test_the_prover_reports_its_tree_while_it_works(monkeypatch):
    """Inside one certificate the live status follows the proof: its phase, node count, mu."""
    import numpy as np

    from app.analyses.mceip_mu.proven import mceip_mu
    from app.analyses.mceip_mu.prover import branch, live
    seen = []
    real = branch.Prover._try_cop

    def spy(self, n):
        seen.append(live.LIVE.text())
        return real(self, n)

    monkeypatch.setattr(branch.Prover, "_try_cop", spy)
    rng = np.random.default_rng(2)
    B = rng.normal(size=(8, 8))
    mceip_mu(B @ B.T + 8 * np.eye(8), 3.0 * rng.normal(size=(8, 8)), cap=10.0)
    assert any(t.startswith("onset proof, ") and "tree nodes" in t and "at mu = " in t for t in seen), seen


def test_writing_the_results_is_shown(tmp_path):
    """After the analyses the run writes the proofs (hundreds of MB at 10^6 DOFs) and results.json:
    each gets its line, with as many files as are written."""
    from mpi4py import MPI

    from app.study.driver import run_and_write
    rec = _Recorder()
    scene = parse_scene({"name": "w", "system": {"type": "block", "nx": 8, "ny": 4}, "mu": 1.1,
                         "analyses": ["mceip_mu"]}, "w.yaml")
    run_and_write(scene, MPI.COMM_SELF, tmp_path, Progress(enabled=True, comm=MPI.COMM_SELF, stream=rec))
    n = len(list((tmp_path / "proofs").glob("state_*.npz")))
    texts = [t for _, t in rec.lines]
    assert n > 0 and any(t.startswith(f"writing proofs: {n}/{n} files (100%)") and t.endswith(", done") for t in texts)
    assert any(t.startswith("writing results: 2/2 files (100%)") for t in texts), texts
    assert (tmp_path / "results.json").is_file()


def test_a_long_slepc_solve_shows_progress_and_stops_at_a_ctrl_c(tmp_path):
    """Inside one SLEPc solve that never converges (the necessary condition's eigensolver given an
    unreachable tolerance through its options prefix) the run prints a progress line at least every
    5 s naming the state and the analysis, and a Ctrl-C stops it at the solver's next iteration
    (its C code used to hold the interpreter for the whole solve: the signal waited minutes) with
    the one ``error:`` line and exit status 130."""
    import os
    import signal
    import subprocess
    import threading

    from conftest import PY, ROOT
    scene = tmp_path / "s.yaml"
    scene.write_text("name: nec\nsystem: {type: block, nx: 40, ny: 20}\nmu: 1.1\nanalyses: [necessary]\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([PY, "-m", "app", "run", str(scene), "-o", str(tmp_path / "out"),
                             "-cd_necessary_eps_tol", "1e-300", "-cd_necessary_eps_max_it", "1000000000"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
                            start_new_session=True,
                            # as from a terminal: a pytest-xdist worker ignores SIGINT, and its children would
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines: list[tuple[float, str]] = []
    reader = threading.Thread(target=lambda: lines.extend((time.monotonic(), ln.rstrip("\n")) for ln in proc.stderr))
    reader.start()
    try:
        deadline = time.monotonic() + 300
        while sum("now state 0" in ln and "necessary condition (19)" in ln for _, ln in lines) < 2:
            assert proc.poll() is None and time.monotonic() < deadline, lines
            time.sleep(0.05)
        beats = [t for t, ln in lines if "now state 0" in ln]
        assert beats[1] - beats[0] < 7.5          # one line about every 5 s while the solve runs
        t0 = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=120)
        stopped = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
        reader.join()
    text = "\n".join(ln for _, ln in lines)
    assert code == 130 and "Traceback" not in text, text
    assert lines[-1][1].startswith("error: interrupted by SIGINT") and sum(ln.startswith("error:") for _, ln in lines) == 1
    print(f"stopped {stopped:.2f} s after the Ctrl-C")
    assert stopped < 20, stopped                # seconds, not the minutes of the whole solve
    assert not (tmp_path / "out").exists()
