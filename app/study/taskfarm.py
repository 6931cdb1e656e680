"""A generic MPI task farm: groups of ranks take tasks from a dispatcher as they become free.

:func:`run_farm` splits ``comm`` (``comm.Split``) into groups of ``group_size`` consecutive
ranks (the last may be smaller). World rank 0 dispatches: ``handle(group, row)`` receives the
row of the task a group finished (None on its first request) and returns the next task index,
or None when there is nothing left. If the MPI library provides ``MPI_THREAD_MULTIPLE``, a thread
on rank 0 answers the requests (point-to-point messages on a duplicate of ``comm``) and rank 0
also works; otherwise rank 0 is a dedicated dispatcher. With one rank the tasks simply run one
after the other.

Waiting ranks sleep between MPI tests instead of spinning in blocking calls, so idle ranks do not
steal cores from working ones on an oversubscribed machine.
"""
from __future__ import annotations

import math
import os
import sys
import threading
import traceback
from typing import Any, Callable, Optional

from app.common.waiting import sleep_until

TAG_REQUEST, TAG_REPLY = 7101, 7102
DISPATCHER_ENV = "CONTACT_DIVERGENCE_SWEEP_DISPATCHER"   # "dedicated": force a non-working rank 0 (tests)
Handle = Callable[[int, Optional[dict]], Optional[int]]
Work = Callable[[int, Any], Optional[dict]]


def _serve(farm, handle: Handle, n_groups: int) -> None:
    """Answer the group leaders' requests until every group has been told to stop."""
    from mpi4py import MPI
    active, sends = n_groups, []
    status = MPI.Status()
    while active:
        sleep_until(lambda: farm.Iprobe(source=MPI.ANY_SOURCE, tag=TAG_REQUEST, status=status))
        source = status.Get_source()
        group, row = farm.recv(source=source, tag=TAG_REQUEST)
        idx = handle(group, row)
        sends.append(farm.isend(idx, dest=source, tag=TAG_REPLY))
        if idx is None:
            active -= 1
    sleep_until(lambda: MPI.Request.Testall(sends))


def _serve_or_abort(farm, handle: Handle, n_groups: int) -> None:
    from mpi4py import MPI
    try:
        _serve(farm, handle, n_groups)
    except KeyboardInterrupt:         # a signal to this rank: the command line reports it (one line)
        raise
    except BaseException:             # noqa: BLE001 - the workers would wait forever
        traceback.print_exc()
        print("error: the task dispatcher failed; aborting all ranks", file=sys.stderr, flush=True)
        MPI.COMM_WORLD.Abort(1)


def run_farm(comm, group_size: int, handle: Optional[Handle], work: Work) -> str:
    """Run tasks over ``comm`` (MPI collective); returns a description of the scheduler used.

    ``handle`` (given on rank 0 only): the dispatcher, see the module docstring.
    ``work(idx, group_comm)``: runs task ``idx`` collectively on the group's communicator; its
    return value on the group's rank 0 (the row) is passed to ``handle`` with the next request.
    """
    from mpi4py import MPI
    if comm.size == 1:
        row = None
        while (idx := handle(0, row)) is not None:
            row = work(idx, comm)
        return "serial (one rank)"
    threaded = (MPI.Query_thread() >= MPI.THREAD_MULTIPLE
                and os.environ.get(DISPATCHER_ENV, "") != "dedicated")
    first = 0 if threaded else 1
    n_groups = math.ceil((comm.size - first) / group_size)
    color = (comm.rank - first) // group_size if comm.rank >= first else MPI.UNDEFINED
    farm = comm.Dup()
    gcomm = comm.Split(color, comm.rank)
    thread = None
    if comm.rank == 0:
        if threaded:
            thread = threading.Thread(target=_serve_or_abort, args=(farm, handle, n_groups),
                                      name="task-dispatcher", daemon=True)
            thread.start()
        else:
            _serve_or_abort(farm, handle, n_groups)
    if gcomm != MPI.COMM_NULL:
        row = None
        while True:
            idx = None
            if gcomm.rank == 0:
                req = farm.isend((color, row), dest=0, tag=TAG_REQUEST)
                sleep_until(lambda: farm.Iprobe(source=0, tag=TAG_REPLY))
                idx = farm.recv(source=0, tag=TAG_REPLY)
                req.wait()
            if gcomm.size > 1:
                idx = gcomm.bcast(idx, root=0)
            if idx is None:
                break
            row = work(idx, gcomm)
        gcomm.Free()
    if thread is not None:
        thread.join()
    barrier = comm.Ibarrier()
    sleep_until(barrier.Test)
    farm.Free()
    how = "world rank 0 dispatches (thread) and works" if threaded else "dedicated dispatcher on world rank 0"
    return f"{how}; {n_groups} group(s) of up to {group_size} rank(s)"
