"""Ranks that wait sleep, and the rank they wait for uses their cores.

Much of an analysis on the contact DOFs runs on rank 0 alone (the exact reduction of
MCEIP-lambda^2, the values of the necessary condition (19): dense work and factorisations of the
whole ``K + t M`` gathered there) while the other ranks wait for its answer. Waiting in a blocking
broadcast, Open MPI polls (yielding the core between polls with ``mpi_yield_when_idle``), rank 0
runs one BLAS thread (the app's default under ``mpirun``), and under ``mpirun``'s default binding
(one core per rank for up to two ranks) it could not use the other cores anyway: they did nothing
useful.

:func:`alone_on_rank_zero` is that broadcast done differently: the waiting ranks poll a
nonblocking barrier and sleep between polls (:func:`sleep_until`), and meanwhile rank 0 widens
its own CPU affinity to the cores of the waiting ranks on its node (:class:`NodeCores`, gathered
once) and lets the BLAS (OpenBLAS: MUMPS's dense fronts, numpy's LAPACK) run as many threads,
each rank's share of threads times the ranks there; and its MPI does not yield the core when
idle (MUMPS's solves probe for messages: :func:`app.common.runtime.mpi_progress_not_yielding`).
All is restored before the answer is broadcast. The answers do not depend on it: every budget
counts work, and one BLAS thread or two gives the same factorisations and eigenvalues up to
rounding, as one rank and two ranks already did (one rank runs OpenBLAS with every core's thread).
"""
from __future__ import annotations

import os
import socket
import time
from dataclasses import dataclass
from typing import Any, Callable, TypeVar

T = TypeVar("T")

#: longest sleep between two polls of a waiting rank; the first polls come sooner (a short
#: answer is not held up by a whole interval)
POLL_SECONDS = 0.01


def sleep_until(test: Callable[[], Any], poll: float = POLL_SECONDS) -> Any:
    """Call ``test`` until it returns something true, sleeping between calls (50 microseconds at
    first, doubling up to ``poll`` seconds); return that."""
    wait = 5e-5
    while True:
        done = test()
        if done:
            return done
        time.sleep(wait)
        wait = min(2.0 * wait, poll)


@dataclass(frozen=True)
class NodeCores:
    """The CPUs that rank 0 may use while the other ranks of its node wait for it: the union of
    their affinity masks and its own (``cpus``), and the BLAS threads to run meanwhile
    (``threads``: each rank's share times the ranks on the node, at most the CPUs)."""

    cpus: frozenset[int]
    threads: int


def node_cores(comm) -> NodeCores | None:
    """:class:`NodeCores` of ``comm``'s rank 0 (None on the other ranks, and on rank 0 where the
    platform has no affinity masks). MPI collective: every rank sends its host name and mask."""
    from app.linalg import blas_threads_now
    try:
        mask = sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        mask = None
    got = comm.gather((socket.gethostname(), mask, blas_threads_now()), root=0)      # MPI collective
    if comm.rank != 0 or got[0][1] is None:
        return None
    host = got[0][0]
    here = [(m, n) for h, m, n in got if h == host and m is not None]
    cpus = frozenset(c for m, _ in here for c in m)
    return NodeCores(cpus, max(1, min(len(cpus), sum(n for _, n in here))))


def alone_on_rank_zero(comm, work: Callable[[], T], cores: NodeCores | None) -> T:
    """``work()`` on rank 0 alone, its answer broadcast to every rank (MPI collective; ``cores``
    from :func:`node_cores`, once per communicator). The other ranks sleep until rank 0 is done,
    and rank 0 runs ``work`` on their cores (its affinity widened, ``cores.threads`` BLAS threads),
    both restored afterwards. An exception of ``work`` is raised on rank 0 and, as a
    RuntimeError with its message, on the others, so that they stay in step."""
    from app.common.runtime import mpi_progress_not_yielding
    from app.linalg import blas_threads, start_blas_workers
    if comm.size == 1:
        with mpi_progress_not_yielding():
            return work()
    got: Any = None
    if comm.rank == 0:
        try:
            with _borrowed(cores) as borrowed:
                # more threads only on the cores borrowed (not where the mask could not be widened)
                threads = cores.threads if cores and borrowed.held else None
                if threads:
                    start_blas_workers(threads)
                with blas_threads(threads), mpi_progress_not_yielding():
                    got = (True, work())
        except Exception as err:          # every rank raises (below), after the broadcast
            failure = err
            got = (False, f"{type(err).__name__}: {err}")
    sleep_until(comm.Ibarrier().Test)                                                # MPI collective
    ok, answer = comm.bcast(got, root=0)                                             # MPI collective
    if not ok:
        if comm.rank == 0:
            raise failure
        raise RuntimeError(answer)
    return answer


class _borrowed:
    """Context: every thread of this process (``/proc/self/task``; the calling thread alone where
    that is not readable) on ``cores.cpus``, so that BLAS threads already started and those
    started inside (they inherit the mask) run on the borrowed cores; each thread's own mask back
    afterwards. Nothing where ``cores`` is None or a mask cannot be changed; ``held``: the
    calling thread runs on ``cores.cpus``."""

    def __init__(self, cores: NodeCores | None):
        self.cores, self.saved, self.held = cores, {}, False

    def __enter__(self):
        if self.cores is None:
            return self
        try:
            tids = [int(t) for t in os.listdir("/proc/self/task")]
        except (OSError, ValueError):
            tids = [0]
        for tid in tids:
            try:
                mask = os.sched_getaffinity(tid)
                if mask != self.cores.cpus:
                    os.sched_setaffinity(tid, self.cores.cpus)
                    self.saved[tid] = mask
            except (AttributeError, OSError):    # a thread that has ended, or no affinity here
                continue
        try:
            self.held = os.sched_getaffinity(0) == self.cores.cpus
        except (AttributeError, OSError):
            self.held = False
        return self

    def __exit__(self, *exc) -> None:
        for tid, mask in self.saved.items():
            try:
                os.sched_setaffinity(tid, mask)
            except OSError:
                continue
