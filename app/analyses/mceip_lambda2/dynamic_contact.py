"""The dynamic contact Schur complements of a system (docs/method.md section 7): ``(K, M)`` seen
from the contact DOFs as functions of ``t = lambda^2 >= 0``, shared by every classification of a
path. ``W(t) = B (K + t M)^-1 B^T`` is the dynamic contact flexibility and ``Z(t) = W(t)^-1`` the
dynamic contact Schur complement (``Z(0)`` the static one of the condensed MCEIP-mu): from the
dense eigen-decomposition ``K Phi = M Phi Omega`` on small systems
(``W(t) = B Phi (Omega + t)^-1 Phi^T B^T``), from MUMPS's partial factorisation of ``K + t M``
(its Schur complement onto the contact DOFs) above ``McpSettings.lambda2_exact_max_dofs``. The
exact slip-node reduction of :mod:`app.analyses.mceip_lambda2.exact` reads them.
"""
from __future__ import annotations

import functools
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
from petsc4py import PETSc

from app.analyses.pencils.reduced import axpy_structure, dense, eliminate_static
from app.analyses.pencils.state import sequential_km, system_cache
from app.linalg import lu_solver
from app.loading.mumps_schur import SchurComplements, static_schur, without_static

#: bytes of the dynamic Schur complements ``Z(t)`` kept per system (least recently used dropped first),
#: and the fewest kept whatever their size: one proof uses some 25 values of ``t`` and the next
#: classification mostly the same ones, so a cache smaller than that recomputes them in turn (at
#: 10^6 DOFs, 1,418 contact DOFs, 16 MB each, 512 MB hold only 32)
CACHE_BYTES = 512 * 2**20
CACHE_ENTRIES = 48


@dataclass
class DynamicContact:
    """``(K, M)`` seen from the contact DOFs (paper axes, order ``T_0, N_0, T_1, ...``), shared by
    every classification of one system: ``flexibility(t)`` is the dynamic contact flexibility
    ``W(t) = B (K + t M)^-1 B^T``; :meth:`at` inverts it to the dynamic contact Schur complement
    ``Z(t)``, kept for the next classifications (the proofs evaluate ``t`` on one dyadic grid per
    system, so neighbouring classifications mostly reuse them)."""

    flexibility: Callable[[float], np.ndarray]
    mass_flexibility: Callable[[], np.ndarray]    # B M^-1 B^T
    Kcc: np.ndarray               # K and M on the contact DOFs, paper axes
    Mcc: np.ndarray
    seconds: float                # time of the set-up (eigen-decomposition or gathering)
    method: str
    evaluations: int = 0          # Z(t) computed (cache misses)
    schur: Callable[[float], np.ndarray | None] | None = None   # Z(t) directly, where available
    _cache: OrderedDict = field(default_factory=OrderedDict, repr=False)
    _mass_schur: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def from_dense(cls, K: np.ndarray, M: np.ndarray, dofs: np.ndarray, signs: np.ndarray) -> "DynamicContact":
        """From dense ``K`` and ``M`` through the eigen-decomposition ``K Phi = M Phi Omega``
        (``scipy.linalg.eigh``: ``K`` symmetric, ``M`` SPD): ``W(t) = B Phi (Omega + t)^-1 Phi^T B^T``.
        ``dofs`` the contact DOFs in the order ``T_0, N_0, T_1, ...`` and ``signs`` their paper-axis
        signs; the time it took is kept in ``seconds``."""
        t0 = time.perf_counter()
        w, Phi = scipy.linalg.eigh(K, M)
        BP = signs[:, None] * Phi[dofs, :]
        sK = signs[:, None] * K[np.ix_(dofs, dofs)] * signs[None, :]
        sM = signs[:, None] * M[np.ix_(dofs, dofs)] * signs[None, :]
        # Phi^T M Phi = I, so M^-1 = Phi Phi^T
        return cls(lambda t: (BP / (w + t)) @ BP.T, lambda: BP @ BP.T, sK, sM, time.perf_counter() - t0,
                   "dense (K, M) eigen-decomposition")

    @classmethod
    def from_sparse(cls, K: PETSc.Mat, M: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray,
                    own: Callable[..., None] | None = None, static: np.ndarray | None = None) -> "DynamicContact":
        """From sequential sparse ``K`` and ``M`` (the caller keeps them alive while this is used):
        each ``Z(t)`` is MUMPS's Schur complement of ``K + t M`` onto the contact DOFs
        (:class:`app.loading.mumps_schur.SchurComplements`, one partial factorisation; its PETSc
        objects handed to ``own``); where MUMPS cannot give it, ``W(t)`` is the signed contact
        block of ``(K + t M)^-1`` from one sparse Cholesky factorisation and MUMPS's selected
        entries of the inverse (:func:`app.loading.flexibility.flexibility_inverse`; block solves
        with the contact columns when the factor cannot give them).

        ``static``: DOFs without mass (the mixed element's pressure, ``K`` a saddle-point matrix
        with an invertible pressure block) that the result eliminates (docs/method.md section 10):
        ``Z(t)`` is unchanged (the quotient property of Schur complements: the pressure is among
        the eliminated DOFs; the interior is factorised as symmetric indefinite), the contact block
        ``K_cc`` is that of ``K_e = K / K_pp`` and the mass's Schur complement is that of ``M``
        without the pressure rows."""
        from app.loading.flexibility import flexibility_inverse, flexibility_matsolve
        t0 = time.perf_counter()
        structure = axpy_structure(K, M)
        mixed = static is not None and len(static) > 0

        def contact_block_of_inverse(A: PETSc.Mat, at: np.ndarray = dofs) -> np.ndarray:
            ksp = lu_solver(A, prefix="cd_dynamic_", factor="cholesky", mumps=True)
            try:
                W = flexibility_inverse(ksp, at, signs)
                if W is None:
                    W = flexibility_matsolve(ksp, A, at, signs)
                if W is None:
                    raise RuntimeError("the factorisation of K + t M gave no contact flexibility")
                return W
            finally:
                ksp.destroy()

        def flexibility(t: float) -> np.ndarray:
            A = K.copy()
            try:
                A.axpy(t, M, structure=structure)
                return contact_block_of_inverse(A)
            finally:
                A.destroy()

        # Z(t) directly from MUMPS's partial factorisation of K + t M, on one matrix whose values
        # change with t (ordering and symbolic analysis once): 0.2 s per t at 100k DOFs where the
        # factorisation and the contact block of its inverse took 0.44 s
        held: dict = {}
        into = (structure if structure == PETSc.Mat.Structure.SAME_NONZERO_PATTERN
                else PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)

        def schur(t: float) -> np.ndarray | None:
            if "A" not in held:
                held["A"] = K.copy()
                held["A"].axpy(1.0, M, structure=structure)     # the union pattern (values reset below)
                held["schur"] = SchurComplements(held["A"], dofs, "cd_dynamic_", spd=not mixed)
                if own is not None:
                    own(held["schur"], held["A"])
            held["A"].zeroEntries()
            held["A"].axpy(1.0, K, structure=into)
            held["A"].axpy(t, M, structure=into)
            Z = held["schur"]()
            return None if Z is None else signs[:, None] * Z * signs[None, :]

        rows = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        try:
            Kcc, Mcc = (X.createSubMatrices(rows, rows)[0] for X in (K, M))
            sK, sM = (signs[:, None] * Y.getValues(range(len(dofs)), range(len(dofs))) * signs[None, :]
                      for Y in (Kcc, Mcc))
            Kcc.destroy()
            Mcc.destroy()
        finally:
            rows.destroy()
        mass_flexibility = functools.partial(contact_block_of_inverse, M)
        if mixed:
            sK = signs[:, None] * static_schur(K, dofs, static) * signs[None, :]
            mass_flexibility = functools.partial(_without, M, static, contact_block_of_inverse, dofs)
        return cls(flexibility, mass_flexibility, sK, sM, time.perf_counter() - t0,
                   "MUMPS's Schur complement of K + t M onto the contact DOFs per t"
                   + (" (the pressure eliminated with the interior)" if mixed else ""), schur=schur)

    def mass_schur(self) -> np.ndarray:
        """The Schur complement of ``M`` onto the contact DOFs (paper axes), computed once."""
        if self._mass_schur is None:
            W = self.mass_flexibility()
            Z = np.linalg.inv(0.5 * (W + W.T))
            self._mass_schur = 0.5 * (Z + Z.T)
        return self._mass_schur

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``Z(t)`` (dynamic contact Schur complement of ``K + t M``) and ``H_cc(t)``."""
        return self.schur_at(t), self.Kcc + t * self.Mcc

    def schur_at(self, t: float) -> np.ndarray:
        """``Z(t)``, the dynamic contact Schur complement of ``K + t M``."""
        Z = self._cache.get(t)
        if Z is None:
            Z = None if self.schur is None else self.schur(t)
            if Z is None:
                W = self.flexibility(t)
                Z = np.linalg.inv(0.5 * (W + W.T))
                Z = 0.5 * (Z + Z.T)
            self.evaluations += 1
            while self._cache and (len(self._cache) + 1) * Z.nbytes > max(CACHE_BYTES, CACHE_ENTRIES * Z.nbytes):
                self._cache.popitem(last=False)
            self._cache[t] = Z
        else:
            self._cache.move_to_end(t)
        return Z


def _without(M: PETSc.Mat, static: np.ndarray, block_of_inverse: Callable, dofs: np.ndarray) -> np.ndarray:
    """``block_of_inverse`` of ``M`` without the rows and columns ``static`` (which hold nothing),
    at the contact DOFs ``dofs`` renumbered accordingly."""
    Mu, at = without_static(M, static, dofs)
    try:
        return block_of_inverse(Mu, at)
    finally:
        Mu.destroy()


def dynamic_contact(system, max_dense_dofs: int) -> DynamicContact | None:
    """The system's :class:`DynamicContact` on rank 0 (None on the other ranks), built on first use:
    dense up to ``max_dense_dofs`` DOFs, sparse factorisations above (MPI collective: K and M
    gathered on rank 0 when distributed). None on rank 0 too when ``(K, M)`` is not SPD."""
    return system_cache(system).once("dynamic", lambda: _build(system, max_dense_dofs))


def _build(system, max_dense_dofs: int) -> DynamicContact | None:
    comm = system.comm
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
    static = system.static_dofs
    mixed = static is not None and len(static) > 0
    K, M = system.K, system.mass()
    if system.n_dofs <= max_dense_dofs:
        Kd, Md = dense(K), dense(M)                                  # MPI collective
        if comm.rank != 0:
            return None
        try:
            if mixed:         # the pressure eliminated first (its block is invertible: nu < 1/2)
                Kd, Md, keep = eliminate_static(Kd, Md, static)
                Kd = 0.5 * (Kd + Kd.T)
                dofs = np.searchsorted(keep, dofs)
            return DynamicContact.from_dense(Kd, Md, dofs, signs)
        except (np.linalg.LinAlgError, ValueError):
            return None
    pair = sequential_km(system)                                    # MPI collective (first call)
    if pair is None:
        return None
    K, M = pair
    return DynamicContact.from_sparse(K, M, dofs, signs, system.own, static if mixed else None)
