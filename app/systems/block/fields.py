"""The built-in block's :class:`app.systems.base.FieldSource`: fields from the contact reactions
and the prescribed motion of CD (``load["u_x"]``, ``load["u_y"]``)."""
from __future__ import annotations

from typing import Optional

import numpy as np
from petsc4py import PETSc

from app.systems.stress import von_mises


class BlockFields:
    """Fields of the block (paper axes: T = +x, N = -y on AB, the line y = 0 the obstacle)."""

    def __init__(self, cfg, ops, flex, nodes):
        self.cfg, self.ops, self.flex = cfg, ops, flex
        self.V = ops.V
        self.length_scale = float(max(cfg.length, cfg.height))
        n = len(nodes)
        self.contact_xy = np.column_stack([[nd.x for nd in nodes], np.zeros(n)])
        self.tangent = np.column_stack([[float(nd.sign_T) for nd in nodes], np.zeros(n)])
        self.normal = np.column_stack([np.zeros(n), [float(nd.sign_N) for nd in nodes]])
        self.gaps = np.zeros(n)
        self.W = flex.W
        self.obstacle = {"point": [0.0, 0.0], "normal": [0.0, -1.0]}

    def von_mises(self, u):
        """UFL expression of the von Mises stress of the displacement ``u`` (the block's E, nu and plane
        model); the mixed element's also reads the pressure of the field :meth:`to_function` made
        last (``ops.pressure``)."""
        cfg = self.cfg
        if self.ops.pressure is not None:
            from app.systems.stress import mixed_von_mises
            return mixed_von_mises(u, self.ops.pressure, cfg.E / (2.0 * (1.0 + cfg.nu)), 2.0 * cfg.nu, cfg.plane)
        from app.systems.elasticity import lame_parameters
        mu, lmbda = lame_parameters(cfg.E, cfg.nu, cfg.plane)
        return von_mises(u, mu, lmbda, cfg.plane)

    @staticmethod
    def _cd(load: Optional[dict]) -> tuple[float, float]:
        return (0.0, 0.0) if load is None else (float(load["u_x"]), float(load["u_y"]))

    def response(self, load: Optional[dict], r: np.ndarray) -> PETSc.Vec:
        """Reduced displacement for the state's motion of CD (``load["u_x"]``, ``load["u_y"]``; none
        when ``load`` is None) and the contact reactions ``r`` in paper axes (one solve with the
        factorised K; the caller destroys the vector)."""
        return self.flex.field(*self._cd(load), r)

    def to_function(self, u: PETSc.Vec, load: Optional[dict]):
        """The whole displacement field of the reduced ``u`` with CD moved as ``load`` says, as a
        DOLFINx Function of ``V``."""
        return self.ops.to_function(u, *self._cd(load))
