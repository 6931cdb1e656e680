"""The loading path walked on rank 0 and streamed to the other ranks, which meanwhile prove the
classifications it has passed (two or more MPI ranks).

The loading path is a sequence of increments, each starting from the previous state, and its
dense work on the contact flexibility W is the same on every rank; the condensed MCEIP-mu of the
classifications (paper (21)-(23)) is independent per chain of classifications. So instead of every rank
walking the same path and then sharing out the MCEIP-mu jobs, rank 0 walks it alone and sends each
state as soon as it is made (non-blocking, pickled); the other ranks classify the states as they
arrive and run the MCEIP-mu jobs rank 0's path has passed, chain by chain and one job at a time
(:class:`app.study.scheduler.EarlyChains`). Rank 0 joins the jobs left after its path. The
chains, and so every answer, are those of one rank.

Used when the system type's loading needs no MPI (``walker``, app/systems/) and the scene asks
for MCEIP-mu alone with the condensed method: the other analyses solve distributed eigenproblems
(SLEPc on the system's communicator) that every rank must enter together.
"""
from __future__ import annotations

import time

from mpi4py import MPI

from app.common.errors import UnreachableLoad
from app.common.interrupt import checkpoint

#: MPI tag of the streamed states (a communicator of its own is duplicated for them)
_TAG = 7


def applies(scene, comm: MPI.Comm, kind) -> bool:
    """Whether the path is streamed: two or more ranks, a system type that walks alone, and
    MCEIP-mu (condensed) the only analysis asked for."""
    return (comm.size > 1 and list(scene.analyses) == ["mceip_mu"]
            and scene.settings.mceip_mu_method == "condensed" and kind.walks_alone())


def walk(comm: MPI.Comm, walk_path, progress, stages, per_state, early) -> tuple[list, dict]:
    """Walk the path on rank 0, sending each state to the other ranks, then classify them into
    ``per_state`` (:class:`app.study.run.Classified`); on the other ranks receive them into
    ``per_state`` (the states that need every rank postponed) and run the MCEIP-mu jobs of the
    chains they open. Returns ``(states, path_info)`` on every rank (MPI
    collective); a path that fails on rank 0 fails on every rank, an
    :class:`app.common.errors.UnreachableLoad` with the same message."""
    link = comm.Dup()                                                    # MPI collective
    try:
        if comm.rank == 0:
            return _send(link, walk_path, progress, stages, per_state)
        return _receive(link, stages, per_state, early)
    finally:
        link.Free()                                                      # MPI collective


def _send(link: MPI.Comm, walk_path, progress, stages, per_state) -> tuple[list, dict]:
    """Rank 0: the path, each state sent to every other rank as it is made; then its own
    classification of the states (``per_state.add_all``) while the last transfers complete."""
    requests = []

    def send(state) -> None:
        requests.extend(link.isend(("state", state), dest=r, tag=_TAG) for r in range(1, link.size))
        # a state is larger than Open MPI's eager limit: the transfer moves on only while this
        # rank is inside MPI, so the sends are tested at every state rather than once at the end
        if MPI.Request.Testall(requests):
            requests.clear()

    try:
        states, info = walk_path(progress, send)
    except UnreachableLoad as err:
        end = ("unreachable", (str(err), err.key))
        raise
    except BaseException as err:
        end = ("failed", f"{type(err).__name__}: {err}")
        raise
    else:
        end = ("end", (info, list(stages.warnings)))
    finally:
        requests.extend(link.isend(end, dest=r, tag=_TAG) for r in range(1, link.size))
        if end[0] != "end":
            MPI.Request.waitall(requests)
    per_state.add_all(states)
    MPI.Request.waitall(requests)
    return states, info


def _receive(link: MPI.Comm, stages, per_state, early) -> tuple[list, dict]:
    """Ranks > 0: the states from rank 0 into ``per_state``, and the jobs of the chains they
    complete, one job at a time, every waiting state received first (rank 0's transfer of a
    state, larger than the eager limit, waits until it is received here)."""
    states = []

    def waiting() -> bool:
        return link.Iprobe(source=0, tag=_TAG)

    while True:
        while not waiting():
            early.work(waiting)       # returns when a state arrives or no job can run
            if not waiting():
                checkpoint()          # a Ctrl-C is seen while waiting (app/common/interrupt.py)
                time.sleep(2e-4)
        kind, body = link.recv(source=0, tag=_TAG)
        if kind != "state":
            break
        states.append(body)
        job = per_state.add(body, postpone=True)
        if job is not None:
            early.add(*job)
    early.chains.close()
    if kind == "unreachable":
        raise UnreachableLoad(body[0], key=body[1])
    if kind == "failed":
        raise RuntimeError(f"the loading path failed on rank 0: {body}")
    info, warnings = body
    stages.warnings[:] = warnings
    if not per_state.postponed:       # (else rank 0 waits for this rank in their broadcasts first)
        early.work()                  # while rank 0 classifies its states
    return states, info
