"""The discrete system seen by the stability code (DESIGN.md sections 1 and 6).

One abstraction serves the two-particle scene and the finite element block: PETSc stiffness and
(lazily built) mass matrices, the contact candidate nodes with their tangential and normal DOFs,
and the dense Schur complement of K onto the contact DOFs (the inverse of the contact
flexibility W = B K^-1 B^T) used by the exact condensation of MCEIP-mu.

Axes: the stability code works in the paper's axes (T tangential, N the body's outward normal),
``u_T = sign_T * u[dof_T]`` and ``u_N = sign_N * u[dof_N]``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.stages import Stages


@dataclass(frozen=True)
class ContactNode:
    """A contact candidate node: its position along the contact side and its two DOFs."""
    id: int
    x: float
    dof_T: int
    dof_N: int
    sign_T: int = 1
    sign_N: int = 1


@dataclass
class System:
    """Elastic system with frictional contact candidates (paper eq. (3)-(7))."""
    comm: MPI.Comm
    K: PETSc.Mat
    nodes: list[ContactNode]
    units: dict[str, str]
    stages: Stages
    build_mass: Callable[[], PETSc.Mat]
    build_contact_schur: Callable[[], np.ndarray]
    description: str = ""
    extra: dict = field(default_factory=dict)
    _M: Optional[PETSc.Mat] = field(default=None, repr=False)
    _Sc: Optional[np.ndarray] = field(default=None, repr=False)

    @property
    def n_dofs(self) -> int:
        return self.K.getSize()[0]

    def mass(self) -> PETSc.Mat:
        """Mass matrix M, assembled on first use only (recorded as the stage 'assemble mass matrix')."""
        if self._M is None:
            with self.stages("assemble mass matrix"):
                self._M = self.build_mass()
        return self._M

    def contact_schur(self) -> np.ndarray:
        """Dense Schur complement of K onto all contact DOFs, paper axes, order (T_0, N_0, T_1, ...).

        Replicated on every rank. Equals W^-1 with W = B K^-1 B^T the contact flexibility.
        """
        if self._Sc is None:
            with self.stages("contact Schur complement"):
                self._Sc = self.build_contact_schur()
        return self._Sc

    def __enter__(self) -> "System":
        return self

    def __exit__(self, *exc) -> None:
        self.destroy()

    def destroy(self) -> None:
        flex = self.extra.get("flexibility")
        if flex is not None:
            flex.destroy()
        for obj in self.extra.get("owned", ()):     # PETSc objects a builder handed over
            obj.destroy()
        self.K.destroy()
        if self._M is not None:
            self._M.destroy()
