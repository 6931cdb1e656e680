"""The discrete system seen by the stability code (docs/method.md sections 1 and 6).

One abstraction serves the two-particle scene and the finite element block: PETSc stiffness and
(lazily built) mass matrices, the contact candidate nodes with their tangential and normal DOFs,
and the dense Schur complement of K onto the contact DOFs (the inverse of the contact
flexibility W = B K^-1 B^T) used by the exact condensation of MCEIP-mu.

Axes: the stability code works in the paper's axes (T tangential, N the body's outward normal),
``u_T = sign_T * u[dof_T]`` and ``u_N = sign_N * u[dof_N]``.

Systems with a mesh also carry a :class:`FieldSource` (``System.fields``): what the field outputs
(app/io/fields.py: ParaView files, screenshots) need to rebuild displacement fields, with no
knowledge of the body's shape; systems without one (matrices, two particles) have ``None``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Protocol

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.common.stages import Stages


@dataclass(frozen=True)
class ContactNode:
    """A contact candidate node: its position along the contact side and its two DOFs."""

    id: int
    x: float
    dof_T: int
    dof_N: int
    sign_T: int = 1
    sign_N: int = 1


class FieldSource(Protocol):
    """Displacement fields of a meshed system, in the system's own DOFs (collective methods).

    ``response(load, r)`` solves ``K u = f(load) + B^T r`` (paper eq. (3)) with the factorised K:
    ``f(load)`` the right-hand side of the state's prescribed loading (prescribed displacements,
    tractions, body force; ``load`` is a state's ``load`` record, None for no loading) and ``r``
    the contact reactions in paper axes (T_0, N_0, T_1, ...). ``to_function(u, load)`` adds the
    prescribed displacements of that loading and returns the whole field as a DOLFINx Function of
    ``V`` (node frames rotated back to x/y). ``contact_xy``, ``tangent`` and ``normal`` are the
    contact nodes' coordinates and their own unit tangent and outward normal in global x/y
    (``u = t u_T + n u_N`` at node i), ``gaps`` their initial gaps (a state's ``u_N`` is the
    normal displacement minus the gap), ``W`` the contact flexibility in paper axes.
    ``obstacle`` is the rigid line (``point``, ``normal``: the body's outward normal) or circle
    (``centre``, ``radius``, ``side``) when there is one.
    """

    V: object
    length_scale: float
    contact_xy: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    gaps: np.ndarray
    W: np.ndarray
    obstacle: Optional[dict]

    def von_mises(self, u) -> object:
        """UFL expression of the von Mises stress of the displacement ``u`` (the body's materials)."""

    def response(self, load: Optional[dict], r: np.ndarray) -> PETSc.Vec:
        """Displacement in the system's DOFs (the caller destroys the vector)."""

    def to_function(self, u: PETSc.Vec, load: Optional[dict]):
        """The whole displacement field, prescribed DOFs included."""


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
    fields: Optional[FieldSource] = None     # displacement fields (None: no mesh)
    #: the factorised contact flexibility W = B K^-1 B^T (app/loading/flexibility.py), and a
    #: builder's assembled operators: destroyed with the system (their K is ``K``)
    flexibility: Optional[Any] = None
    operators: Optional[Any] = None
    #: other PETSc objects made for this system (by its builder or an analysis, :meth:`own`)
    owned: list = field(default_factory=list)
    #: the signed curvature of a curved obstacle at each contact node (None: a straight obstacle)
    curvature: Optional[np.ndarray] = None
    #: what the system type's own loading path needs besides the above (a dataclass of its
    #: ``path.py``; None when it needs nothing more)
    loading_input: Optional[Any] = None
    #: what the analyses keep between this system's classifications, made on first use and
    #: dropped with the system (:class:`app.analyses.pencils.state.SystemCache`)
    analysis_cache: Optional[Any] = None
    #: DOFs without mass that the analyses eliminate statically (the mixed element's pressure,
    #: docs/method.md section 10): global indices, ascending, replicated; None when there are none
    static_dofs: Optional[np.ndarray] = None
    #: the static DOFs are a constraint (an incompressible material, nu = 1/2: their block of K is
    #: singular, zero), which the analyses cannot eliminate by a Schur complement
    static_constraint: bool = False
    _M: Optional[PETSc.Mat] = field(default=None, repr=False)
    _Sc: Optional[np.ndarray] = field(default=None, repr=False)

    @property
    def n_dofs(self) -> int:
        """Number of DOFs of the system (the global size of ``K``)."""
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

    @property
    def has_static_dofs(self) -> bool:
        """Whether some DOFs carry no mass and are eliminated statically (:attr:`static_dofs`)."""
        return self.static_dofs is not None and len(self.static_dofs) > 0

    def own(self, *objs) -> None:
        """Hand PETSc objects made for this system (by an analysis) over to it: :meth:`destroy`
        destroys them with the system's own."""
        self.owned.extend(objs)

    def destroy(self) -> None:
        """Destroy the system's PETSc objects: a builder's factorisation and operators, the objects it
        handed over (:attr:`owned`), ``K`` and the mass matrix if it was built."""
        for obj in (self.flexibility, self.operators):
            if obj is not None and hasattr(obj, "destroy"):
                obj.destroy()
        for obj in self.owned:
            obj.destroy()
        self.owned.clear()
        self.K.destroy()
        if self._M is not None:
            self._M.destroy()
