"""``system.type: two_particles``: the two-particle system of the paper, section 5 and Fig. 1
(the paper's Fig. 1 and Table 1; docs/method.md section 4), and its single equilibrium state."""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from app.common.stages import Stages
from app.loading.state import EquilibriumState
from app.systems.base import ContactNode, System
from app.systems.discrete import discrete_system
from app.systems.particles.schema import TwoParticles
from app.systems.units import DISCRETE_UNITS as UNITS


def particle_matrices(k: float, m: float, phi_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Dense K and M of the paper's Fig. 1, DOFs (u_T1, u_N1, u_T2, u_N2)."""
    c, s = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    K = k * np.array([[c * c + 1, -c * s, -1.0, 0.0],
                      [-c * s, s * s + 1, 0.0, 0.0],
                      [-1.0, 0.0, c * c + 1, c * s],
                      [0.0, 0.0, c * s, s * s + 1]])
    return K, m * np.eye(4)


def supported_matrices(K: np.ndarray, M: np.ndarray, k_T: float, k_N: float, m_s: float) -> tuple[np.ndarray, np.ndarray]:
    """K' and M' of the two particles resting on a third particle held by springs ``k_T``, ``k_N``
    to the ground, in the DOFs ``(q_1, q_2, v)``: ``q_i = u_i - v`` the particles' displacements
    relative to the support (their contact DOFs) and ``v`` the support's (an interior node):
    ``u = P (q, v)`` with ``P = [[I, E], [0, I]]``, ``E = [I; I]``, unimodular, ``K' = P^T K P``
    (docs/method.md section 10)."""
    K6 = np.zeros((6, 6))
    K6[:4, :4] = K
    K6[4:, 4:] = np.diag([k_T, k_N])
    M6 = np.zeros((6, 6))
    M6[:4, :4] = M
    M6[4:, 4:] = m_s * np.eye(2)
    P = np.eye(6)
    P[0:2, 4:6] = P[2:4, 4:6] = np.eye(2)
    return P.T @ K6 @ P, P.T @ M6 @ P


def build(cfg: TwoParticles, comm: MPI.Comm, stages: Stages, units: str = "mm-N-MPa-tonne-s") -> System:
    """System of the two-particle scene: both particles are contact nodes, no interior DOFs.

    ``units`` is the scene's unit system (the labels of results.json ``units``)."""
    u = UNITS[units]
    K, M = particle_matrices(cfg.k, cfg.m, cfg.phi_deg)
    nodes = [ContactNode(id=0, x=0.0, dof_T=0, dof_N=1), ContactNode(id=1, x=1.0, dof_T=2, dof_N=3)]
    ob = cfg.obstacle
    where = "" if ob.type == "line" else f", on a circle of radius {ob.radius} {u['length']} ({ob.side})"
    sup = cfg.support
    if sup is not None:
        K, M = supported_matrices(K, M, sup.k_T, sup.k_N, sup.m)
        where = (f", on a supported particle (k_T={sup.k_T} {u['stiffness']}, k_N={sup.k_N} {u['stiffness']}, "
                 f"m={sup.m} {u['mass']})")
    system = discrete_system(K, M, nodes, comm, stages, u,
                             f"two particles, k={cfg.k} {u['stiffness']}, m={cfg.m} {u['mass']}, "
                             f"phi={cfg.phi_deg} deg{where}")
    if ob.type != "line":      # the curvature terms of the pencils (app/analyses/pencils/curvature.py)
        system.curvature = np.full(2, ob.curvature())
    return system


def path(scene, comm: MPI.Comm, stages: Stages, progress=None):
    """The paper's two-particle state: both particles in impending slip with signs S1, S2.

    The scene fixes the signs and the normal reaction P (``normal_reaction``, default 1 N):
    r_N = -P, r_T = S mu P. On the straight line the pencils do not depend on P; on a circle
    they do, through kappa P (docs/method.md section 8).
    Returns ``(system, [state], path_info)``.
    """
    cfg: TwoParticles = scene.system
    with stages("build system"):
        system = build(cfg, comm, stages, scene.units)
    S = np.array(cfg.signs, dtype=float)
    mu_state = max(scene.mu, 1e-300)
    P = cfg.normal_reaction
    state = EquilibriumState(index=0, load={}, u_T=np.zeros(2), u_N=np.zeros(2),
                             r_T=S * mu_state * P, r_N=-P * np.ones(2))
    return system, [state], {"end": "single equilibrium state"}
