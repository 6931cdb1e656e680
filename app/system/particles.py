"""The two-particle system of the paper, section 5 and Fig. 1 (DESIGN.md section 4)."""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from app.config import TwoParticles
from app.stages import Stages
from app.system.base import ContactNode, System
from app.system.discrete import discrete_system

UNITS = {"length": "mm", "force": "N", "stiffness": "N/mm", "mass": "tonne",
         "lambda2": "1/s^2", "mu": "1"}


def particle_matrices(k: float, m: float, phi_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Dense K and M of the paper's Fig. 1, DOFs (u_T1, u_N1, u_T2, u_N2)."""
    c, s = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    K = k * np.array([[c * c + 1, -c * s, -1.0, 0.0],
                      [-c * s, s * s + 1, 0.0, 0.0],
                      [-1.0, 0.0, c * c + 1, c * s],
                      [0.0, 0.0, c * s, s * s + 1]])
    return K, m * np.eye(4)


def two_particle_system(cfg: TwoParticles, comm: MPI.Comm, stages: Stages) -> System:
    """System of the two-particle scene: both particles are contact nodes, no interior DOFs."""
    K, M = particle_matrices(cfg.k, cfg.m, cfg.phi_deg)
    nodes = [ContactNode(id=0, x=0.0, dof_T=0, dof_N=1), ContactNode(id=1, x=1.0, dof_T=2, dof_N=3)]
    return discrete_system(K, M, nodes, comm, stages, UNITS,
                           f"two particles, k={cfg.k} N/mm, m={cfg.m} tonne, phi={cfg.phi_deg} deg")
