"""The Gmsh body's :class:`app.systems.base.FieldSource` (``system.type: gmsh``): displacement fields
from a state's contact reactions and its load parameters, for the field outputs
(app/io/fields.py). The operators it uses are built by :func:`app.systems.gmsh.operators.body_operators`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from app.systems.gmsh.schema import GmshBody


@dataclass
class FieldData:
    """What :class:`BodyFields` needs of the assembly (app/systems/gmsh/operators.py ``body_operators``)."""

    V: object                                     # the displacement space (vector Lagrange)
    prescribed: dict[str, dict[int, np.ndarray]]  # curve -> component -> local unrolled DOFs (incl. ghosts)
    kept_local: np.ndarray                        # local unrolled indices of the owned kept DOFs, reduced order
    dof_x: np.ndarray                             # (local DOF blocks, 2) coordinates
    mu: object                                    # Lamé parameters per cell (DG0 functions; the mixed
    lmbda: object                                 # element: mu and the bulk compliance 1/kappa)
    Q: object = None                              # the mixed element's pressure space (P1), else None
    two_nu: object = None                         # the mixed element's 2 nu per cell (DG0)


def parameter_name(key: tuple) -> str:
    """Name of a load parameter in a state's ``load["parameters"]`` (as
    :func:`app.systems.gmsh.path._phases` writes it)."""
    return ".".join(x for x in key if x)


class BodyFields:
    """The body's :class:`app.systems.base.FieldSource`: fields from a state's contact reactions and
    its load parameters (``load["parameters"]``), in the obstacle-rotated reduced DOFs.

    ``response``: ``K' u' = sum_j a_j f'_j + B^T r`` with the rotated unit loads ``f'_j`` and the
    reactions at the contact DOFs (already in the node frames, sign +1); ``to_function``: ``u = R u'``
    on the kept DOFs and the prescribed motions (translation + linearised rotation about the origin,
    as the parameters hold them) on the prescribed curves. ``ops`` is the body's
    :class:`app.systems.gmsh.operators.BodyOperators`, ``flex`` its contact flexibility.
    """

    def __init__(self, cfg: GmshBody, ops, flex, gaps: np.ndarray):
        import dolfinx.fem
        self.cfg, self.ops, self.flex = cfg, ops, flex
        self.V = ops.field_data.V
        # the mixed element: the pressure of the last field made (to_function), read by von_mises
        Q = ops.field_data.Q
        self.pressure = dolfinx.fem.Function(Q, name="pressure") if Q is not None else None
        self.length_scale = ops.size                  # the body's bounding-box size
        tvec, nvec = cfg.obstacle.frame()
        n = len(ops.contact_xy)
        self.contact_xy = ops.contact_xy
        self.tangent = np.tile(tvec, (n, 1))      # one straight obstacle: every node has its frame
        self.normal = np.tile(nvec, (n, 1))
        self.gaps = gaps
        self.W = flex.W
        if cfg.obstacle.type == "circle":
            self.obstacle = {"centre": [float(v) for v in cfg.obstacle.centre], "radius": float(cfg.obstacle.radius),
                             "side": cfg.obstacle.side}
        elif cfg.obstacle.type == "body":         # drawn as the mesh it is, deformed with the body
            self.obstacle = None
        elif cfg.obstacle.type == "curve":
            self.obstacle = {"polyline": cfg.obstacle.geometry().polyline().tolist(), "side": cfg.obstacle.side}
        else:
            self.obstacle = {"point": [float(v) for v in cfg.obstacle.point], "normal": [float(v) for v in nvec]}
        self._index = {parameter_name(k): j for k, j in ops.params.items()}

    def von_mises(self, u):
        """UFL expression of the von Mises stress of the displacement ``u`` (Lamé parameters per cell:
        the material of each physical surface); the mixed element's also reads :attr:`pressure`,
        the pressure of the field :meth:`to_function` made last."""
        from app.systems.stress import mixed_von_mises, von_mises
        d = self.ops.field_data
        if self.pressure is not None:
            return mixed_von_mises(u, self.pressure, d.mu, d.two_nu, self.cfg.plane)
        return von_mises(u, d.mu, d.lmbda, self.cfg.plane)

    def _parameters(self, load: dict | None) -> np.ndarray:
        a = np.zeros(len(self._index))
        for name, val in ((load or {}).get("parameters") or {}).items():
            a[self._index[name]] = float(val)
        return a

    def response(self, load: dict | None, r: np.ndarray) -> PETSc.Vec:
        """Reduced, rotated displacement for the state's load parameters and the contact reactions
        ``r`` (see the class docstring; the caller destroys the vector)."""
        a = self._parameters(load)
        return self.flex.response([(a[j], self.ops.loads[j]) for j in np.flatnonzero(a)], r)

    def to_function(self, u: PETSc.Vec, load: dict | None):
        """The whole displacement field in x/y as a DOLFINx Function of ``V``: the reduced ``u`` rotated
        back from the node frames on the kept DOFs, the prescribed curves moved as the state's load
        parameters say (translation and linearised rotation about the origin)."""
        import dolfinx.fem
        d = self.ops.field_data
        a = self._parameters(load)
        w = u.duplicate()
        try:
            self.ops.R.mult(u, w)                     # node frames -> x/y
            f = dolfinx.fem.Function(self.V, name="displacement")
            f.x.array[:] = 0.0
            values = w.getArray(readonly=True)
            f.x.array[d.kept_local] = values[:len(d.kept_local)]
            if self.pressure is not None:            # then the rank's pressure DOFs (mixed element)
                self.pressure.x.array[:len(values) - len(d.kept_local)] = values[len(d.kept_local):]
                self.pressure.x.scatter_forward()
        finally:
            w.destroy()
        bs = self.V.dofmap.index_map_bs
        for name, comps in d.prescribed.items():
            t = {kind: a[self._index[parameter_name(("motion", name, kind))]]
                 for kind in ("tx", "ty", "rz") if ("motion", name, kind) in self.ops.params}
            for c, loc in comps.items():
                xy = d.dof_x[loc // bs]
                val = t.get("tx" if c == 0 else "ty", 0.0)
                if "rz" in t:                              # u = theta (-y, x), linearised
                    val = val + t["rz"] * (-xy[:, 1] if c == 0 else xy[:, 0])
                f.x.array[loc] = val
        f.x.scatter_forward()
        return f
