"""The deferred condensed MCEIP-mu of every distinct classification, spread over the MPI ranks.

:func:`app.analyses.runner.analyse_state` leaves the condensed MCEIP-mu of each classification
:class:`~app.analyses.outcomes.Deferred`; :func:`analyse_condensed_distributed` runs them in chains (warm starts
along the path), one rank per chain, and gathers the answers on every rank.

Under MPI the ranks other than 0 may start before the loading path ends (:class:`EarlyChains`,
driven by app/study/stream.py): they run the jobs of each chain as rank 0's path passes their
classifications, while rank 0 is still walking; the chains, and so the answers, are the same.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from app.analyses.mceip_mu.prover.live import LIVE
from app.analyses.outcomes import Failed, MceipMuOutcome, Outcome, one_line
from app.analyses.pencils.reduced import UnsupportedState
from app.analyses.pencils.state import StatePencils
from app.analyses.runner import ANALYSES, state_mceip_mu
from app.common.interrupt import checkpoint
from app.common.progress import Progress
from app.loading.classify import ZERO, Classification
from app.scene.schema import Scene
from app.systems.base import System


def analyse_condensed_distributed(system: System, scene: Scene, jobs: list[tuple[Classification, dict[str, Outcome]]],
                                  comm, progress=None, early: "EarlyChains | None" = None) -> list[tuple[int, str]]:
    """The deferred condensed MCEIP-mu of ``jobs`` (classification, its analyses: name -> outcome,
    in path order).

    The jobs with more than ``mcp.search_full_max`` slip nodes are cut into chains of at most
    ``mcp.warm_chain`` consecutive classifications, each job of a chain warm-started from the
    previous job's solutions (neighbouring classifications differ by about one node); every
    other job is a chain of its own (:func:`_chains`). Each chain runs on one
    rank alone (dense s x s work on COMM_SELF objects); under MPI the ranks take the next chain
    from a shared counter (one-sided atomic fetch-and-add on rank 0's window), the most expensive
    chains first, so a rank that finishes early takes more. The chains do not depend on the
    number of ranks, and the results are gathered on every rank (``allgather``; the stored pencils
    on rank 0 only, which writes them), so the output is
    the same on any number of ranks. Replaces the :class:`~app.analyses.outcomes.Deferred` of each
    job's analyses by its outcome in place (order as in :func:`app.analyses.runner.analyse_state`);
    returns the failures ``(job, reason)``.

    ``progress`` (an :class:`app.common.progress.Progress`): rank 0 shows the classifications done over
    all ranks, the one it runs now (its s), the last it finished (proven or not) and the time
    left estimated from the cost model of :func:`_cost`.

    ``early``: the :class:`EarlyChains` that ranks other than 0 have been working on during the
    loading path (its counter and answers); the remaining chains are taken in path order."""
    if early is not None:
        return early.finish(jobs, progress)
    system.contact_schur()        # collective the first time: built on every rank before the split
    mcp = scene.settings.mcp
    slips = [len(cls.slip) for cls, _ in jobs]
    chains = _chains(slips, mcp.warm_chain, mcp.search_full_max)
    order = _chain_order(slips, chains)
    mine: dict[int, MceipMuOutcome | Failed] = {}
    total_cost = float(sum(_cost(s) for s in slips))

    def run_chain(c: int, tasks, counter=None) -> None:
        _run_chain(system, scene, jobs, chains[c], mine, tasks, counter)

    def tasks(done=None):
        shown = progress or Progress(enabled=False, comm=comm)
        return shown.tasks(len(jobs), "MCEIP-mu", unit="classification", total_cost=total_cost, done=done)

    if comm.size == 1:
        with tasks() as t:
            for c in order:
                run_chain(c, t)
    else:
        error = None
        with _SharedCounter(comm) as counter:                           # MPI collective (window)
            with tasks(counter.done if comm.rank == 0 else None) as t:
                try:
                    while (i := counter.next()) < len(order):           # one-sided, rank 0's window
                        run_chain(order[i], t, counter)
                except Exception as err:      # this rank stops taking chains; the collectives stay matched
                    error = err
                comm.Barrier()        # MPI collective: every rank done (rank 0 keeps reporting meanwhile)
        _raise_on_every_rank(comm, error)                                # MPI collective
    return _gather(comm, jobs, mine)                                     # MPI collective


def _run_chain(system: System, scene: Scene, jobs: list[tuple[Classification, dict[str, Outcome]]],
               chain: list[int], mine: dict[int, MceipMuOutcome | Failed], tasks, counter=None,
               first: int | None = None) -> None:
    """The condensed MCEIP-mu of the jobs of ``chain`` on this rank alone, each warm-started
    from the previous job's solutions (except the chain's ``first`` job, default ``chain[0]``);
    the outcomes (or the :class:`Failed` of an analysis error) go into ``mine``. ``tasks``:
    progress; ``counter``: the shared :class:`_SharedCounter`."""
    first = chain[0] if first is None else first
    for k in chain:
        checkpoint()              # a Ctrl-C whose KeyboardInterrupt was swallowed (app/common/interrupt.py)
        cls = jobs[k][0]
        s = len(cls.slip)
        warm = _warm_starts(jobs[k - 1][0], mine.get(k - 1), cls) if k != first else None
        LIVE.reset()
        tasks.start(f"s = {s}", detail=LIVE.text)
        p = StatePencils(system, cls)
        try:
            mine[k] = state_mceip_mu(system, p, scene, s, replicated=False, warm=warm)
        except (UnsupportedState, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
            mine[k] = one_line(err)
        finally:
            p.destroy()
        if counter is not None:
            counter.add_done(_cost(s))                                   # one-sided, rank 0's window
        tasks.finish(f"s = {s} {_proof_word(mine[k])}", _cost(s))


class EarlyChains:
    """The deferred MCEIP-mu jobs of a study handed out while rank 0 still walks the loading path
    (two or more ranks; app/study/stream.py).

    Ranks other than 0 receive the states as rank 0 makes them, classify them and :meth:`add`
    each new deferred job; :meth:`work` runs the jobs of the chains (:class:`Chains`) taken from
    the shared counter in path order, one job at a time as they arrive. Rank 0 adds nothing while
    it walks; after the path every rank calls :meth:`finish` with the study's jobs (the same on
    every rank), which runs the jobs left and gathers the answers as
    :func:`analyse_condensed_distributed` does. The chains depend on the jobs and settings only,
    and each job is warm-started from the previous one of its chain as there, so the answers are
    those of one rank.

    Created and finished collectively (the counter is an MPI window)."""

    def __init__(self, system: System, scene: Scene, comm):
        system.contact_schur()        # collective the first time: built on every rank before the split
        self.system, self.scene, self.comm = system, scene, comm
        mcp = scene.settings.mcp
        self.chains = Chains(mcp.warm_chain, mcp.search_full_max)
        self.jobs: list[tuple[Classification, dict[str, Outcome]]] = []
        self.mine: dict[int, MceipMuOutcome | Failed] = {}
        self.error: Exception | None = None
        self._ticket: int | None = None            # the chain this rank holds
        self._next = 0                             # its next job (position in the chain)
        self._counter = _SharedCounter(comm)       # MPI collective (window)
        self._tasks = Progress(enabled=False, comm=comm).tasks(0, "MCEIP-mu")
        self._finished = False

    def __enter__(self) -> "EarlyChains":
        return self

    def __exit__(self, *exc) -> None:
        if not self._finished:        # left early (an error): the window is freed all the same
            self._finished = True
            self._counter.__exit__(None, None, None)                     # MPI collective

    def add(self, cls: Classification, analyses: dict[str, Outcome]) -> None:
        """One more deferred job, in path order (ranks other than 0, during the path)."""
        self.jobs.append((cls, analyses))
        self.chains.add(len(cls.slip))

    def work(self, waiting=lambda: False) -> None:
        """Run the jobs of the chains this rank takes, one at a time, until the chain it holds
        waits for jobs the path has not reached yet, or ``waiting()`` says states have arrived
        (they are received first: a sender's transfer waits for its receive)."""
        chains = self.chains.chains
        while self.error is None:
            if self._ticket is None:
                self._ticket, self._next = self._counter.next(), 0      # one-sided, rank 0's window
            c = self._ticket
            if c >= len(chains):
                return                # the chain does not exist yet (or never will)
            if self._next < len(chains[c]):
                try:
                    _run_chain(self.system, self.scene, self.jobs, [chains[c][self._next]], self.mine, self._tasks,
                               self._counter, first=chains[c][0])
                except Exception as err:  # this rank stops taking chains; the collectives stay matched
                    self.error = err
                self._next += 1
                if waiting():
                    return
            elif c < self.chains.complete:
                self._ticket = None   # done with this chain
            else:
                return                # its next job is still to come

    def finish(self, jobs: list[tuple[Classification, dict[str, Outcome]]], progress=None) -> list[tuple[int, str]]:
        """After the path (MPI collective): the jobs left, on every rank, then the answers
        gathered into ``jobs`` (this rank's own list, equal to the one built during the path)."""
        comm = self.comm
        if not self.jobs:             # rank 0: nothing received, the study's own list
            for cls, analyses in jobs:
                self.add(cls, analyses)
        elif [cls.key for cls, _ in self.jobs] != [cls.key for cls, _ in jobs]:
            self.error = self.error or RuntimeError(f"rank {comm.rank} classified other jobs during the path")
        self.chains.close()
        total_cost = float(sum(_cost(len(cls.slip)) for cls, _ in jobs))
        shown = progress or Progress(enabled=False, comm=comm)
        with shown.tasks(len(jobs), "MCEIP-mu", unit="classification", total_cost=total_cost,
                         done=self._counter.done if comm.rank == 0 else None) as t:
            self._tasks = t
            self.work()
            comm.Barrier()            # MPI collective: every rank done (rank 0 keeps reporting meanwhile)
        self._finished = True
        self._counter.__exit__(None, None, None)                         # MPI collective (window freed)
        _raise_on_every_rank(comm, self.error)                           # MPI collective
        return _gather(comm, self.jobs, self.mine)                       # MPI collective


def _gather(comm, jobs: list[tuple[Classification, dict[str, Outcome]]],
            mine: dict[int, MceipMuOutcome | Failed]) -> list[tuple[int, str]]:
    """Every rank's answers into the jobs' analyses dicts on every rank (MPI collective); the
    stored pencils (``_proof``, hundreds of MB at large s) on rank 0 only, which writes proofs/.
    Returns the failures ``(job, reason)``."""
    failures = []
    proofs: dict = {}
    if comm.size == 1:
        parts = [mine]                      # nothing to send (and no copy of the pencils)
    else:
        proofs = {k: d.proof for k, d in mine.items() if isinstance(d, MceipMuOutcome) and d.proof is not None}
        for k in proofs:
            mine[k].proof = None
        gathered = comm.gather(proofs, root=0)                           # MPI collective
        if comm.rank == 0:
            proofs = {k: v for part in gathered for k, v in part.items()}
        parts = comm.allgather(mine)                                     # MPI collective
    for part in parts:
        for k, d in part.items():
            if comm.rank == 0 and k in proofs:
                d.proof = proofs[k]
            out = jobs[k][1]
            out["mceip_mu"] = d
            for name in [n for n in ANALYSES if n in out]:               # canonical key order
                out[name] = out.pop(name)
            if isinstance(d, Failed):
                failures.append((k, d.reason))
    return failures


def _raise_on_every_rank(comm, error: Exception | None) -> None:
    """An unexpected error on some rank is raised on every rank (MPI collective): the failing rank
    re-raises its own, the others a RuntimeError naming it, so that no rank waits in a later
    collective for one that has left."""
    what = comm.allgather(None if error is None else f"{type(error).__name__}: {error}")     # MPI collective
    if error is not None:
        raise error
    failed = [(r, w) for r, w in enumerate(what) if w is not None]
    if failed:
        r, w = failed[0]
        raise RuntimeError(f"MCEIP-mu failed on rank {r}: {w}")


class _SharedCounter:
    """Counters on rank 0 that every rank increments atomically (MPI one-sided ``Fetch_and_op``
    under a passive-target lock: no participation of rank 0 needed, it may be computing): the
    next chain to take, and the classifications done with their cost (for progress only)."""

    NEXT, DONE, DONE_COST = 0, 1, 2

    def __init__(self, comm):
        from mpi4py import MPI
        self._MPI = MPI
        self.comm = comm
        self.win = MPI.Win.Allocate(24 if comm.rank == 0 else 0, 8, comm=comm)   # MPI collective
        if comm.rank == 0:
            self._local = np.frombuffer(self.win.tomemory(), dtype=np.int64)
            self._local[:] = 0
        comm.Barrier()                                                     # MPI collective: counters set

    def _add(self, slot: int, value: int) -> int:
        add, got = np.array([value], dtype=np.int64), np.zeros(1, dtype=np.int64)
        self.win.Lock(0, self._MPI.LOCK_SHARED)
        self.win.Fetch_and_op(add, got, 0, slot, self._MPI.SUM)
        self.win.Unlock(0)
        return int(got[0])

    def next(self) -> int:
        """The next chain index (each index is handed out once over all ranks)."""
        return self._add(self.NEXT, 1)

    def add_done(self, cost: float) -> None:
        """One classification done, of (relative) ``cost``."""
        self._add(self.DONE, 1)
        self._add(self.DONE_COST, int(round(cost)))

    def done(self) -> tuple[int, float]:
        """(classifications done, their cost) as last seen in rank 0's window memory (rank 0
        only; a plain read without MPI, so any thread may call it: a display value)."""
        return int(self._local[self.DONE]), float(self._local[self.DONE_COST])

    def __enter__(self) -> "_SharedCounter":
        return self

    def __exit__(self, *exc) -> None:
        self.comm.Barrier()                                                # MPI collective
        self.win.Free()                                                    # MPI collective


class Chains:
    """Jobs (in path order) grouped into chains as they arrive: runs of at most ``chain``
    consecutive jobs with more than ``full_max`` slip nodes (where warm starts are used); every
    other job alone (finer work units balance the ranks better). Depends on the jobs and settings
    only, not on the ranks. ``complete``: how many of the first chains can no longer grow."""

    def __init__(self, chain: int, full_max: int):
        self.chain, self.full_max = chain, full_max
        self.slips: list[int] = []
        self.chains: list[list[int]] = []
        self.complete = 0

    def add(self, s: int) -> None:
        """The next job, with ``s`` slip nodes."""
        k = len(self.slips)
        self.slips.append(s)
        last = self.chains[-1] if self.chains else None
        if s > self.full_max and last is not None and len(last) < self.chain and self.slips[last[-1]] > self.full_max:
            last.append(k)
        else:
            self.chains.append([k])
        last = self.chains[-1]
        grows = self.slips[last[-1]] > self.full_max and len(last) < self.chain
        self.complete = len(self.chains) - (1 if grows else 0)

    def close(self) -> None:
        """No more jobs: every chain is complete."""
        self.complete = len(self.chains)


def _chains(slip_counts: list[int], chain: int, full_max: int) -> list[list[int]]:
    """The :class:`Chains` of jobs with ``slip_counts`` slip nodes."""
    chains = Chains(chain, full_max)
    for s in slip_counts:
        chains.add(s)
    return chains.chains


def _chain_order(slip_counts: list[int], chains: list[list[int]]) -> list[int]:
    """The chains by decreasing estimated cost, the sum of :func:`_cost` (the dense search and
    certificate are cubic in s): big chains first balance the ranks."""
    cost = [sum(_cost(slip_counts[k]) for k in c) for c in chains]
    return sorted(range(len(chains)), key=lambda c: (-cost[c], c))


def _cost(s: int) -> int:
    """Estimated relative cost of the condensed MCEIP-mu of a classification with ``s`` slip nodes."""
    return (s + 1) ** 3


def _proof_word(d: MceipMuOutcome | Failed) -> str:
    """How a finished MCEIP-mu outcome reads in a progress line."""
    if isinstance(d, Failed):
        return "failed"
    return "proven" if d.certified else "not proven"


def _warm_starts(prev: Classification, prev_result: MceipMuOutcome | Failed | None,
                 cls: Classification) -> list[tuple[np.ndarray, float]]:
    """The previous classification's solutions as starts ``(x_Ts, mu)`` on ``cls``'s slip nodes
    (a node that does not slip in ``cls`` is dropped, a new slip node starts at 0)."""
    if not isinstance(prev_result, MceipMuOutcome) or ZERO in prev.status or ZERO in cls.status:
        return []
    where = {int(node): j for j, node in enumerate(cls.slip)}
    out = []
    for sol in prev_result.solutions:
        x = np.zeros(len(where))
        for node, v in zip(prev.slip, sol.x_Ts):
            if int(node) in where:
                x[where[int(node)]] = v
        out.append((x, float(sol.value)))
    return out
