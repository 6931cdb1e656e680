"""The reduced pencils (10)-(16) of one classified state, built lazily, and shared helpers of the analyses.

:class:`StatePencils` builds only what the requested analyses need (the mass matrix only for
(17)-(19) and MCEIP-lambda^2, the condensed pencil only for the condensed MCEIP-mu) and destroys
its PETSc objects in :meth:`StatePencils.destroy`. ``warm_hints`` carries eigenvalues from one
classification to the next along the path (shifts only: every answer is verified).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from petsc4py import PETSc

from app.analyses.pencils import curvature
from app.analyses.pencils.reduced import (
    combine,
    condensed_mu_pencil,
    reduced_pencil,
    reduced_space,
)
from app.common.waiting import alone_on_rank_zero, node_cores
from app.loading.classify import Classification
from app.scene.schema import Scene
from app.systems.base import System

#: most DOFs of a full-size pencil the analyses turn into dense matrices (enumeration of
#: MCEIP-lambda^2, zero-reaction nodes); refused above
FULL_DENSE_LIMIT = 3000


def seq_aij(A: np.ndarray) -> PETSc.Mat:
    """Small dense matrix as a sequential AIJ matrix (replicated problems run on COMM_SELF)."""
    n = A.shape[0]
    M = PETSc.Mat().createAIJ((n, n), nnz=n, comm=PETSc.COMM_SELF)
    rows = np.arange(n, dtype=PETSc.IntType)
    M.setValues(rows, rows, A)
    M.assemble()
    return M


class StatePencils:
    """Lazily built reduced pencils of one state; destroyed at the end of the analyses."""

    def __init__(self, system: System, cls: Classification):
        self.system, self.cls = system, cls
        self._space = None
        self._K = None
        self._M = None
        self._cond = None
        self._star: dict[float, tuple[PETSc.Mat, PETSc.Mat]] = {}

    @property
    def space(self):
        """The kept DOFs of the state (:func:`app.analyses.pencils.reduced.reduced_space`), built on first use."""
        if self._space is None:
            with self.system.stages("reduced pencils"):
                self._space = reduced_space(self.system, self.cls)
        return self._space

    def _reduced(self, A):
        """``reduced_pencil`` of ``A``, on a curved obstacle in the slip nodes' contact frames."""
        space = self.space
        with self.system.stages("reduced pencils"):
            rot = curvature.rotate_petsc(A, self.system, self.cls) if curvature.is_curved(self.cls) else None
            try:
                return reduced_pencil(A if rot is None else rot, self.system, self.cls, space)
            finally:
                if rot is not None:
                    rot.destroy()

    def K(self):
        """``(K0, K1)`` of (16), without the curvature terms (``star`` adds them)."""
        if self._K is None:
            self._K = self._reduced(self.system.K)
        return self._K

    def M(self):
        """``(M0, M1)``, the reduced mass pencil ``M* = M0 + mu M1`` of (15)-(16), built on first use."""
        if self._M is None:
            self._M = self._reduced(self.system.mass())
        return self._M

    def star(self, mu: float) -> tuple[PETSc.Mat, PETSc.Mat]:
        """``(K*(mu), M*(mu))`` of (15), built once and shared by the necessary and sufficient
        conditions; destroyed with the rest. Callers must not modify them. On a curved
        obstacle ``K*(mu) = K0 + G + mu K1 + mu^2 G`` (docs/method.md section 8)."""
        mu = float(mu)
        if mu not in self._star:
            K0, K1 = self.K()
            M0, M1 = self.M()
            with self.system.stages("reduced pencils"):
                Ks = combine(K0, K1, mu)
                if curvature.is_curved(self.cls):
                    curvature.add_geometric(Ks, self.space, self.cls, 1.0 + mu * mu)
                self._star[mu] = (Ks, combine(M0, M1, mu))
        return self._star[mu]

    def condensed_mu_quadratic(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A0, A1, A2)``: the condensed MCEIP-mu on a curved obstacle, ``A0 + mu A1 + mu^2 A2``."""
        Sc = self.system.contact_schur()
        with self.system.stages("condensed pencil"):
            return curvature.condensed_quadratic(Sc, self.cls)

    def condensed_mu(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A0, A1)``: the condensed MCEIP-mu pencil ``A0 + mu A1`` on the slip nodes (21)-(23), built on
        first use from the contact Schur complement; RuntimeError on a curved obstacle, whose
        condensed pencil is quadratic (:meth:`condensed_mu_quadratic`)."""
        if curvature.is_curved(self.cls):
            raise RuntimeError("the condensed pencil of a curved obstacle is quadratic in mu: use condensed_mu_quadratic")
        if self._cond is None:
            Sc = self.system.contact_schur()
            with self.system.stages("condensed pencil"):
                self._cond = condensed_mu_pencil(Sc, self.cls)
        return self._cond

    def destroy(self):
        """Destroy every PETSc object built: the reduced pencils, the ``star`` pencils and the kept
        DOFs."""
        for pair in (self._K, self._M, *self._star.values()):
            if pair is not None:
                for m in pair:
                    m.destroy()
        if self._space is not None:
            self._space.destroy()


#: a field of :class:`SystemCache` not made yet (None is a value: "cannot be made")
_UNSET = object()


@dataclass
class SystemCache:
    """What the analyses keep between the classifications of one system: held by the system
    (``System.analysis_cache``, :func:`system_cache`), so it lives and dies with it."""

    warm: dict[float, dict] = field(default_factory=dict)   # mu -> the previous classification's eigenvalues
    gathered: Any = _UNSET       # sequential K and M on rank 0 (:func:`sequential_km`)
    spectra: Any = _UNSET        # K and M seen from the contact DOFs (app/analyses/conditions/contact_spectrum.py)
    dynamic: Any = _UNSET        # the dynamic contact flexibility (app/analyses/mceip_lambda2/dynamic_contact.py)
    cores: Any = _UNSET          # the cores of rank 0's node (:func:`on_rank_zero`)

    def once(self, name: str, make: Callable[[], Any]) -> Any:
        """Field ``name``, made by ``make()`` on first use."""
        value = getattr(self, name)
        if value is _UNSET:
            value = make()
            setattr(self, name, value)
        return value


def system_cache(system: System) -> SystemCache:
    """The system's :class:`SystemCache`, made on first use."""
    if system.analysis_cache is None:
        system.analysis_cache = SystemCache()
    return system.analysis_cache


def warm_hints(system: System, mu: float) -> dict:
    """Eigenvalues of the previous classification along the path (per system and mu): shifts
    for the next one's eigen solves (they only speed them up; every answer is verified)."""
    return system_cache(system).warm.setdefault(float(mu), {})


def keep_modes(scene: Scene) -> bool:
    """Keep the kept-space mode vectors (``Solution.x``, never written to results.json) for the mode
    fields of app/io/fields.py."""
    outputs = getattr(scene, "outputs", None)
    return bool(outputs is not None and outputs.fields)


def no_slip() -> tuple[str, dict]:
    """The ``result`` and ``search`` record of an MCEIP at a state without slip nodes (no solution)."""
    return "no solution (no slip nodes)", {"note": "no slip nodes: x_Ts is empty, so x = 0 is the only "
                                                   "solution of (12)-(14)/(21)-(23) and there is no eigenvalue",
                                           "complete": True}


def on_rank_zero(system: System, work: Callable[[], Any]) -> Any:
    """``work()`` on rank 0 alone (what it needs is there: the gathered ``K`` and ``M``, the
    contact DOFs' dense data), its answer broadcast to every rank, the other ranks asleep and their
    cores rank 0's meanwhile (:func:`app.common.waiting.alone_on_rank_zero`). MPI collective."""
    cores = system_cache(system).once("cores", lambda: node_cores(system.comm))    # MPI collective (first call)
    return alone_on_rank_zero(system.comm, work, cores)                           # MPI collective


def sequential_km(system) -> tuple[PETSc.Mat, PETSc.Mat] | None:
    """The system's whole ``K`` and ``M`` as sequential matrices on rank 0 (None on the other
    ranks): the system's own on one rank; gathered on rank 0 when distributed, once per system,
    and destroyed with it. MPI collective on the first call."""
    return system_cache(system).once("gathered", lambda: _gather(system))


def _gather(system) -> tuple[PETSc.Mat, PETSc.Mat] | None:
    comm = system.comm
    K, M = system.K, system.mass()
    if comm.size == 1:
        return K, M
    N = system.n_dofs
    rows = PETSc.IS().createStride(N if comm.rank == 0 else 0, 0, 1, comm=PETSc.COMM_SELF)
    try:
        K, M = (X.createSubMatrices(rows, rows)[0] for X in (K, M))     # MPI collective
    finally:
        rows.destroy()
    if comm.rank != 0:
        K.destroy()
        M.destroy()
        return None
    system.own(K, M)
    return K, M
