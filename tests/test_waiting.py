"""Work on rank 0 alone (app/common/waiting.py): the other ranks sleep instead of spinning, rank 0
runs on their cores meanwhile, every rank gets the answer, an error reaches every rank, and the
masks and BLAS threads are back afterwards."""
import json
import os
import subprocess

import pytest
from conftest import PY, ROOT

SCRIPT = """\
import ctypes, json, os, sys, time
sys.path.insert(0, {root!r})
import numpy  # noqa: F401 - OpenBLAS loaded, as in a run
from mpi4py import MPI
from app.common.waiting import alone_on_rank_zero, node_cores
from app.linalg import blas_threads_now

comm = MPI.COMM_WORLD
cores = node_cores(comm)
opal = ctypes.CDLL("libopen-pal.so.40", mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
yielding = ctypes.c_bool.in_dll(opal, "opal_progress_yield_when_idle")     # Open MPI's setting
masks = comm.gather(sorted(os.sched_getaffinity(0)), root=0)
before = (sorted(os.sched_getaffinity(0)), blas_threads_now(), yielding.value)

def work():
    time.sleep(2.0)
    return sorted(os.sched_getaffinity(0)), blas_threads_now(), yielding.value

cpu = time.process_time()
inside = alone_on_rank_zero(comm, work, cores)
waited_cpu = time.process_time() - cpu
after = (sorted(os.sched_getaffinity(0)), blas_threads_now(), yielding.value)
try:
    alone_on_rank_zero(comm, lambda: 1 / 0, cores)
    error = None
except Exception as err:
    error = f"{{type(err).__name__}}: {{err}}"
# one line from rank 0 (two ranks printing at once can share a line of mpirun's output)
rows = comm.gather({{"rank": comm.rank, "masks": masks, "inside": inside, "before": before, "after": after,
                    "waited_cpu": waited_cpu, "error": error}}, root=0)
if comm.rank == 0:
    print("rows: " + json.dumps(rows), flush=True)
"""


@pytest.mark.mpi
def test_rank_zero_works_on_the_cores_of_the_ranks_that_sleep(tmp_path):
    script = tmp_path / "alone.py"
    script.write_text(SCRIPT.format(root=str(ROOT)))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1", OMPI_MCA_mpi_yield_when_idle="1")     # the app's defaults
    # each rank bound to its own core, as mpirun does by default for two ranks
    p = subprocess.run(["mpirun", "-n", "2", "--bind-to", "core", "--map-by", "core", PY, str(script)],
                       capture_output=True, text=True, timeout=120, env=env)
    if p.returncode != 0 and "not enough slots" in (p.stdout + p.stderr).lower():
        pytest.skip("fewer than two cores: mpirun cannot bind two ranks to their own cores")
    assert p.returncode == 0, p.stdout + p.stderr
    got = [json.loads(line[len("rows: "):]) for line in p.stdout.splitlines() if line.startswith("rows: ")]
    assert len(got) == 1, p.stdout + p.stderr
    rows = {r["rank"]: r for r in got[0]}
    assert set(rows) == {0, 1}, p.stdout + p.stderr
    union = sorted(set(rows[0]["masks"][0]) | set(rows[0]["masks"][1]))
    for r in rows.values():
        # the same answer everywhere: rank 0's mask and threads inside the work, and its MPI
        # not yielding the core when idle
        assert r["inside"] == [union, min(len(union), 2), False]
        assert r["after"] == r["before"]                   # masks, threads and yielding restored
        assert r["before"][2] is True
    assert rows[0]["error"] == "ZeroDivisionError: division by zero"
    assert rows[1]["error"] == "RuntimeError: ZeroDivisionError: division by zero"
    assert rows[0]["before"][1] == 1
    # rank 1 slept through rank 0's two seconds of work (Open MPI's blocking barrier spends
    # about one of them polling, yielding or not)
    assert rows[1]["waited_cpu"] < 0.2, rows[1]


def test_one_rank_works_without_mpi_yielding():
    """On one rank too, Open MPI's progress engine does not yield while the work runs (MUMPS's
    solves probe for messages), and its setting is back afterwards, whichever it was."""
    import ctypes

    from mpi4py import MPI

    from app.common.runtime import _opal_yield_setter
    from app.common.waiting import alone_on_rank_zero
    flag = ctypes.c_bool.in_dll(ctypes.CDLL("libopen-pal.so.40", mode=os.RTLD_NOLOAD | os.RTLD_LAZY),
                                "opal_progress_yield_when_idle")
    was = flag.value
    try:
        for before in (True, False):
            _opal_yield_setter()(before)
            assert alone_on_rank_zero(MPI.COMM_SELF, lambda: flag.value, None) is False
            assert flag.value is before
    finally:
        _opal_yield_setter()(was)


def test_no_more_threads_where_the_cores_cannot_be_borrowed():
    """A mask the kernel refuses (here an empty one; in practice CPUs outside the process's
    cpuset) leaves every thread's mask as it was and ``held`` false, so rank 0 does not start
    threads that would share its one core."""
    from app.common.waiting import NodeCores, _borrowed
    before = os.sched_getaffinity(0)
    with _borrowed(NodeCores(frozenset(), 2)) as b:
        assert not b.held
        assert os.sched_getaffinity(0) == before
    assert os.sched_getaffinity(0) == before
    with _borrowed(NodeCores(frozenset(before), 2)) as b:      # its own mask: held, nothing changed
        assert b.held
    assert os.sched_getaffinity(0) == before
