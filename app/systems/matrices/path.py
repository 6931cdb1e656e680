"""``system.type: matrices``: build the System from matrix files and solve its loading path.

The stiffness (and mass) become distributed PETSc AIJ matrices (each rank sets its own rows of
the replicated CSR read at validation). K is factorised once (MUMPS) for the contact
flexibility W = B K^-1 B^T (app/loading/flexibility.py), which feeds both the condensed MCEIP-mu
and the quasi-static contact solve.

Loading path with applied forces (``system.forces``), paper eqs. (1)-(2), (5)-(7): at every step
the total force ``f`` grows by ``force / steps``; its contact displacements with zero reactions
are ``u0 = B K^-1 f`` (one solve per phase, by linearity) and the increment is the block's
complementarity problem (app/loading/contact.py) on the contact stiffness W^-1. Initial gaps
``g0`` enter as a shift of u0: with ``u_N <= g0`` written as ``ũ_N = u_N - g0 <= 0`` the reactions
are ``r = W^-1 (ũ_c - (u0 - g0 e_N))``. States report ``u_N = ũ_N`` (minus the current gap,
the quantity Signorini is written in) so that free nodes have ``u_N < 0``.
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.common.stages import Stages
from app.loading.contact import ContactSolveError, FrictionalContact
from app.loading.flexibility import contact_flexibility
from app.loading.state import EquilibriumState
from app.systems.base import ContactNode, System
from app.systems.matrices.schema import Matrices
from app.systems.units import DISCRETE_UNITS as UNITS

log = logging.getLogger(__name__)


def petsc_from_csr(A, comm: MPI.Comm) -> PETSc.Mat:
    """Distributed AIJ copy of a replicated scipy CSR matrix: every rank sets its own rows."""
    n = A.shape[0]
    mat = PETSc.Mat().createAIJ((n, n), comm=comm)
    rows = PETSc.Vec().createMPI(n, comm=comm)     # default row layout, as createAIJ's
    r0, r1 = rows.getOwnershipRange()
    rows.destroy()
    local = A[r0:r1]
    mat.setPreallocationCSR((local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType),
                             local.data))
    mat.assemble()
    assert mat.getOwnershipRange() == (r0, r1)
    return mat


def _zero_load(K: PETSc.Mat) -> PETSc.Vec:
    v = K.createVecLeft()
    v.zeroEntries()
    return v


def build(cfg: Matrices, comm: MPI.Comm, stages: Stages, units: str = "mm-N-MPa-tonne-s") -> System:
    """The System of a matrices scene: K, lazily M, contact nodes, contact flexibility (MPI collective)."""
    with stages("read matrices"):
        Kcsr = cfg.stiffness()
        K = petsc_from_csr(Kcsr, comm)
    entries = cfg.contact_nodes()
    xs = cfg.positions if cfg.positions is not None else [float(i) for i in range(len(entries))]
    nodes = [ContactNode(id=i, x=float(xs[i]), dof_T=T, dof_N=N, sign_T=sT, sign_N=sN)
             for i, (T, N, sT, sN) in enumerate(entries)]
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in nodes], dtype=float).ravel()
    lx, ly = _zero_load(K), _zero_load(K)
    with stages("factorise K, contact flexibility"):
        flex = contact_flexibility(K, lx, ly, dofs, signs)          # MPI collective

    def build_mass() -> PETSc.Mat:
        M = cfg.mass()
        if M is None:     # the schema requires M for the analyses that call this
            raise RuntimeError("no mass matrix given (system.M)")
        return petsc_from_csr(M, comm)

    system = System(comm=comm, K=K, nodes=nodes, units=UNITS[units], stages=stages, build_mass=build_mass,
                    build_contact_schur=lambda: flex.schur,
                    description=(cfg.description or "system from matrices")
                    + f" (K: {Kcsr.shape[0]} DOFs, {len(nodes)} contact nodes)")
    system.flexibility = flex
    system.own(lx, ly)
    return system


def _contact_values(flex, f: np.ndarray, K: PETSc.Mat) -> np.ndarray:
    """Paper-axis contact displacements ``B K^-1 f`` with zero reactions (one solve, MPI collective)."""
    b = K.createVecLeft()
    try:
        r0, r1 = b.getOwnershipRange()
        b.setArray(f[r0:r1])
        return flex.contact_response(b)
    finally:
        b.destroy()


def _static_state(cfg: Matrices) -> EquilibriumState:
    r = np.array(cfg.state.reactions, dtype=float)
    n = len(r)
    gaps = np.zeros(n) if cfg.gaps is None else np.array(cfg.gaps, dtype=float)
    u_T = np.zeros(n) if cfg.state.u_T is None else np.array(cfg.state.u_T, dtype=float)
    return EquilibriumState(index=0, load={"phase": "given"}, u_T=u_T, u_N=-gaps, r_T=r[:, 0].copy(),
                            r_N=r[:, 1].copy())


def path(scene, comm: MPI.Comm, stages: Stages, progress):
    """``(system, states, path_info)`` of a matrices scene (MPI collective)."""
    cfg: Matrices = scene.system
    system = build(cfg, comm, stages, scene.units)
    if cfg.state is not None:
        return system, [_static_state(cfg)], {"end": "single equilibrium state (given reactions)"}
    flex = system.flexibility
    n = len(system.nodes)
    gaps = np.zeros(n) if cfg.gaps is None else np.array(cfg.gaps, dtype=float)
    G = np.zeros(2 * n)
    G[1::2] = gaps
    states: list[EquilibriumState] = []
    failure = None
    end = "all force phases applied"
    total_steps = sum(ph.steps for ph in cfg.forces)
    with stages("quasi-static loading"):
        solver = FrictionalContact(flex.schur, scene.mu)
        try:
            u_prev = np.zeros(2 * n)          # contact displacements of the last state, shifted by the gaps
            u0_end = np.zeros(2 * n)          # u0 at the end of the previous phase
            bar = progress.bar(total_steps, "loading")
            for p, ph in enumerate(cfg.forces):
                du0 = _contact_values(flex, cfg.force(p), system.K)
                for k in range(1, ph.steps + 1):
                    u0 = u0_end + du0 * (k / ph.steps)
                    try:
                        inc = solver.solve(u0 - G, u_prev[0::2], -u_prev[1::2])
                    except ContactSolveError as err:
                        end = f"contact solve failed in phase {p} at step {k}: {err}"
                        failure = {"state": len(states), "analysis": "contact increment", "reason": end}
                        break
                    u_prev = np.ravel(np.column_stack([inc.u_T, inc.u_N]))
                    load = {"phase": p, "step": k, "factor": k / ph.steps,
                            "normal_resultant": float(-np.sum(inc.r_N)),
                            "tangential_resultant": float(np.sum(inc.r_T))}
                    states.append(EquilibriumState(
                        index=len(states), load=load, u_T=inc.u_T.copy(), u_N=inc.u_N.copy(),
                        r_T=inc.r_T.copy(), r_N=inc.r_N.copy(),
                        extra={"contact_solve": {"iterations": inc.iterations, "method": inc.method,
                                                 "violation": inc.violation}}))
                    bar.update(1)
                if failure:
                    break
                u0_end = u0_end + du0
            bar.close()
        finally:
            solver.destroy()
    from app.loading.sanity import check_finite  # no length scale here: finiteness only (warnings, never an error)
    for w in check_finite(states):
        log.warning("%s", w)
        stages.warnings.append(w)
    return system, states, {"end": end, "phases": len(cfg.forces), "steps": total_steps, "failure": failure}
