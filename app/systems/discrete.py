"""Discrete systems given by small dense matrices (the two-particle scene, random test systems)."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.common.stages import Stages
from app.systems.base import ContactNode, System


def petsc_from_dense(A: np.ndarray, comm: MPI.Comm) -> PETSc.Mat:
    """Distributed AIJ copy of a small dense matrix (every rank sets its own rows)."""
    n = A.shape[0]
    mat = PETSc.Mat().createAIJ((n, n), comm=comm)
    mat.setUp()
    r0, r1 = mat.getOwnershipRange()
    for i in range(r0, r1):
        cols = np.flatnonzero(A[i]).astype(PETSc.IntType)
        mat.setValues(i, cols, A[i, cols])
    mat.assemble()
    return mat


def contact_schur_dense(K: np.ndarray, nodes: list[ContactNode]) -> np.ndarray:
    """Schur complement of K onto the contact DOFs, paper axes, order (T_0, N_0, T_1, ...)."""
    c = np.array([[n.dof_T, n.dof_N] for n in nodes]).ravel()
    sg = np.array([[n.sign_T, n.sign_N] for n in nodes], dtype=float).ravel()
    interior = np.setdiff1d(np.arange(K.shape[0]), c)
    S = K[np.ix_(c, c)]
    if len(interior):
        S = S - K[np.ix_(c, interior)] @ np.linalg.solve(K[np.ix_(interior, interior)], K[np.ix_(interior, c)])
    return sg[:, None] * S * sg[None, :]


def discrete_system(K: np.ndarray, M: np.ndarray, nodes: list[ContactNode], comm: MPI.Comm,
                    stages: Stages, units: dict[str, str], description: str) -> System:
    """A :class:`System` from dense K (SPD) and M (SPD); M is only copied to PETSc when asked for."""
    K = np.array(K, dtype=float)
    M = np.array(M, dtype=float)
    return System(comm=comm, K=petsc_from_dense(K, comm), nodes=nodes, units=units, stages=stages,
                  build_mass=lambda: petsc_from_dense(M, comm),
                  build_contact_schur=lambda: contact_schur_dense(K, nodes),
                  description=description)


def random_contact_problem(rng: np.random.Generator, n_contact: int, n_interior: int, n_slip: int,
                           n_stick: int, mu: float, comm: MPI.Comm, stages: Stages):
    """A random SPD system with a classified state, for property tests and benchmarks.

    Returns ``(system, state)``: the first ``n_slip`` contact nodes (in a random order) slip with
    random signs, the next ``n_stick`` stick and the rest are free.
    """
    from app.loading.state import EquilibriumState
    n = 2 * n_contact + n_interior
    A = rng.standard_normal((n, n))
    K = A @ A.T + 0.5 * n * np.eye(n)
    B = rng.standard_normal((n, n))
    M = B @ B.T / n + np.eye(n)
    perm = rng.permutation(n)
    nodes = [ContactNode(id=i, x=float(i), dof_T=int(perm[2 * i]), dof_N=int(perm[2 * i + 1]),
                         sign_T=int(rng.choice([-1, 1])), sign_N=int(rng.choice([-1, 1])))
             for i in range(n_contact)]
    order = rng.permutation(n_contact)
    r_T, r_N, u_N = np.zeros(n_contact), np.zeros(n_contact), np.zeros(n_contact)
    for rank, i in enumerate(order):
        if rank < n_slip:
            r_N[i], r_T[i] = -1.0, mu * rng.choice([-1.0, 1.0])
        elif rank < n_slip + n_stick:
            r_N[i], r_T[i] = -1.0, 0.5 * mu * rng.uniform(-1, 1)
        else:
            u_N[i] = -1.0
    system = discrete_system(K, M, nodes, comm, stages, {"length": "1", "force": "1"}, "random")
    state = EquilibriumState(index=0, load={}, u_T=np.zeros(n_contact), u_N=u_N, r_T=r_T, r_N=r_N)
    return system, state
