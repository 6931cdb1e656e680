"""``system.type: gmsh``: the System of a 2D body from a Gmsh file and its loading program
(app/loading/program.py).

:func:`build` takes the body's reduced, obstacle-rotated operators (app/systems/gmsh/operators.py:
K, the mass, the load parameters, the contact DOFs in the obstacle frames), factorises K for the
contact flexibility and the contact responses ``U0`` of the unit load parameters, and checks the
initial position against the obstacle; :func:`path` turns the program's phases into load
parameter increments and runs them (app/loading/program.py); the contact tractions of every
state are recovered from the nodal reactions (app/systems/gmsh/contact_traction.py). The body's
displacement fields (ParaView files, screenshots) are in app/systems/gmsh/fields.py.
"""
from __future__ import annotations

import logging
import pathlib
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.common.errors import UnreachableLoad, point_text
from app.common.stages import Stages
from app.loading.program import ProgramPhase, run_program
from app.systems.base import ContactNode, System
from app.systems.gmsh.contact_traction import ContactRecovery, contact_recovery
from app.systems.gmsh.fields import BodyFields, parameter_name
from app.systems.gmsh.operators import BodyError, body_operators
from app.systems.gmsh.schema import GmshBody
from app.systems.units import CONTINUUM_UNITS as UNITS
from app.systems.units import implausible_material

log = logging.getLogger(__name__)


SINGULAR = ("system.prescribed: the stiffness is singular: the prescribed curves do not fix every rigid motion of the body: prescribe "
            "a curve or give system.foundation (a weak elastic foundation)")


@dataclass(frozen=True)
class LoadingInput:
    """What the loading path of a Gmsh body needs besides K and the contact flexibility
    (``System.loading_input``)."""

    U0: np.ndarray                 # paper-axis contact displacements of each unit load parameter (columns)
    gaps: np.ndarray               # initial normal gap of each contact node
    params: dict                   # (kind, curve, component) -> load parameter index
    contact_xy: np.ndarray         # the contact nodes' coordinates
    recovery: ContactRecovery      # nodal reactions -> contact tractions
    obstacle: Optional[Any] = None  # a curved obstacle's geometry (None: the straight line)


def _check_left_out(cfg: GmshBody, ops, stages: Stages) -> None:
    """A warning when nodes of the contact curve with one prescribed component are left out of the
    contact set (they are not kept out of the obstacle)."""
    if not len(ops.left_out):
        return
    gl = cfg.obstacle.clearance(ops.left_out)
    i = int(np.argmin(gl))
    g = float(gl[i]) if abs(gl[i]) > 1e-10 * ops.size else 0.0
    w = (f"{len(ops.left_out)} node(s) of the contact curve '{cfg.contact}' have one prescribed component and are "
         f"left out of the contact set (not kept out of the obstacle), e.g. {point_text(ops.left_out[i], ops.size)} "
         f"with initial gap {g:.3g}")
    log.warning("%s", w)
    stages.warnings.append(w)


def _check_materials(cfg: GmshBody, units: str, stages: Stages) -> None:
    """A warning for each material whose E or density no real solid has in the scene's units."""
    named = {"system.material": cfg.material} if cfg.material else {f"system.materials.{k}": m for k, m in cfg.materials.items()}
    if cfg.obstacle.type == "body":
        named["system.obstacle.material"] = cfg.obstacle.material
    for key, m in named.items():
        for w in implausible_material(key, m.E, m.density, units):
            log.warning("%s", w)
            stages.warnings.append(w)


def _contact_columns(flex, loads: list[PETSc.Vec]) -> np.ndarray:
    """U0: paper-axis contact displacements of every unit load parameter (one solve each, collective)."""
    cols = [flex.contact_response(b) for b in loads]
    return np.column_stack(cols) if cols else np.zeros((len(flex.dofs), 0))


def _check_curve_start(cfg: GmshBody, ops, depth: float, where, body: float, frac: float) -> None:
    """The body starts on its side of a curve obstacle, every contact node facing the curve
    (its closest point not an end of the curve)."""
    if depth < -1e-10 * body and frac > 0.5:
        other = "right" if cfg.obstacle.side == "left" else "left"
        raise BodyError(f"system.obstacle.side = '{cfg.obstacle.side}': the body starts on the other side of the curve "
                        f"'{cfg.obstacle.physical}' ({100 * frac:.0f} % of its nodes, up to {-depth:.3g} beyond it at "
                        f"{point_text(where, body)}): the body is on its {other}, looking along the curve's direction")
    ends = cfg.obstacle.geometry().at_end(ops.contact_xy)
    if np.any(ends):
        i = int(np.flatnonzero(ends)[0])
        raise BodyError(f"system.obstacle.physical = '{cfg.obstacle.physical}': the contact node at "
                        f"{point_text(ops.contact_xy[i], body)} lies beyond an end of the curve (its closest point is "
                        "the end, not the foot of a normal): extend the curve past the contact curve")


def build(cfg: GmshBody, comm: MPI.Comm, stages: Stages, units: str = "mm-N-MPa-tonne-s") -> System:
    """System of the body, with the contact flexibility and the unit-load contact responses (collective)."""
    from app.loading.flexibility import contact_flexibility
    ops = body_operators(cfg, comm, stages)
    n = len(ops.contact_dofs)
    tvec, nvec = cfg.obstacle.frame()
    s = cfg.obstacle.coordinate(ops.contact_xy)          # along the line, or the arc coordinate on a circle
    nodes = [ContactNode(id=i, x=float(s[i]), dof_T=int(ops.contact_dofs[i, 0]), dof_N=int(ops.contact_dofs[i, 1]))
             for i in range(n)]
    dofs = ops.contact_dofs.ravel()
    signs = np.ones(2 * n)
    zero = ops.K.createVecLeft()
    zero.zeroEntries()
    with stages("factorise K, contact flexibility"):
        try:
            flex = contact_flexibility(ops.K, zero, zero, dofs, signs)          # MPI collective
        except PETSc.Error:
            raise BodyError(SINGULAR) from None
        # A (nearly) singular K gives a huge or indefinite flexibility: W k is O(1 ... 1e4) for a held
        # body (k the largest diagonal entry of K), O(1/eps) for a floating one.
        diag = ops.K.getDiagonal()
        kmax = diag.norm(PETSc.NormType.NORM_INFINITY)                            # MPI collective
        diag.destroy()
        if (not np.all(np.isfinite(flex.W)) or np.linalg.eigvalsh(flex.W).min() <= 0
                or np.abs(flex.W).max() * kmax > 1e10):
            raise BodyError(SINGULAR)
        U0 = _contact_columns(flex, ops.loads)
    size = max(float(np.ptp(ops.contact_xy, axis=0).max()), 1e-300)
    gaps = cfg.obstacle.clearance(ops.contact_xy)
    gaps[np.abs(gaps) <= 1e-10 * size] = 0.0
    depth, where, body, frac = ops.deepest
    if depth < -1e-10 * body and frac > 0.5 and cfg.obstacle.type == "circle":
        raise BodyError(f"system.obstacle: the body starts inside the obstacle ({100 * frac:.0f} % of its nodes, up to "
                        f"{-depth:.3g} at {point_text(where, body)}; {cfg.obstacle.describe()}): check centre, radius "
                        "and side (outside: the body outside the circle, inside: in the bore)")
    if cfg.obstacle.type == "curve":
        _check_curve_start(cfg, ops, depth, where, body, frac)
    if depth < -1e-10 * body and frac > 0.5:
        raise BodyError(f"system.obstacle: the body starts on the obstacle's side of the line ({100 * frac:.0f} % of its "
                        f"nodes, up to {-depth:.3g} beyond it at {point_text(where, body)}; line through "
                        f"{tuple(cfg.obstacle.point)}, outward normal {tuple(np.round(nvec, 6))}): the normal must "
                        "point from the body into the obstacle")
    if np.any(gaps < 0):
        i = int(np.argmin(gaps))
        raise BodyError(f"system.obstacle: the contact node at {point_text(ops.contact_xy[i], body)} "
                        f"starts {-gaps[i]:.3g} inside the obstacle: move the obstacle's point or the body")
    if depth < -1e-10 * body:
        what = cfg.obstacle.type if cfg.obstacle.curved else "line"
        w = (f"part of the body starts beyond the obstacle {what} ({100 * frac:.2g} % of its nodes, up to {-depth:.3g} "
             f"at {point_text(where, body)}): only the contact curve '{cfg.contact}' is kept out of the obstacle")
        log.warning("%s", w)
        stages.warnings.append(w)
    _check_materials(cfg, units, stages)
    u = UNITS[units]

    def material(m) -> str:
        return f"E = {m.E:g} {u['stress']}, nu = {m.nu:g}, density = {m.density:g} {u['density']}"
    mats = (material(cfg.material) if cfg.material else
            "; ".join(f"{name}: {material(m)}" for name, m in cfg.materials.items()))
    system = System(comm=comm, K=ops.K, nodes=nodes, units=u, stages=stages, build_mass=ops.mass,
                    build_contact_schur=lambda: flex.schur,
                    description=(f"gmsh body {pathlib.Path(cfg.file).name}, {cfg.element_name()}, plane {cfg.plane}, "
                                 f"thickness {cfg.thickness} {u['length']}, {mats}, {cfg.obstacle.describe()}, "
                                 f"{n} contact nodes, {ops.K.getSize()[0]} DOFs"))
    _check_left_out(cfg, ops, stages)
    system.flexibility = flex
    system.static_dofs = ops.static
    system.static_constraint = ops.static is not None and 0.5 in cfg.poisson_ratios().values()
    system.own(ops.R, ops.kept, *ops.loads, zero)
    geometry = None
    if cfg.obstacle.curved:      # the curvature terms of the pencils (app/analyses/pencils/curvature.py)
        geometry = cfg.obstacle.geometry(np.mean(ops.contact_xy, axis=0))
        # at the initial contact points; each state records its own (curved_contact.curvature)
        system.curvature = geometry.curvatures(ops.contact_xy)
    system.loading_input = LoadingInput(U0=U0, gaps=gaps, params=ops.params, contact_xy=ops.contact_xy,
                                        recovery=contact_recovery(ops.contact_edges, ops.contact_xy, cfg.degree),
                                        obstacle=geometry)
    system.fields = BodyFields(cfg, ops, flex, gaps)
    return system


def _phases(cfg: GmshBody, params: dict) -> list[ProgramPhase]:
    P = len(params)
    out = []
    for i, ph in enumerate(cfg.program):
        da = np.zeros(P)            # motions of prescribed curves (what `until` scales)
        fixed = np.zeros(P)         # loads: forces, tractions, gravity
        for name, mo in ph.displacement.items():
            th = np.radians(mo.rotation_deg)
            tx = mo.translation[0] + th * mo.about[1]
            ty = mo.translation[1] - th * mo.about[0]
            for kind, val in (("tx", tx), ("ty", ty), ("rz", th)):
                if ("motion", name, kind) in params:
                    da[params[("motion", name, kind)]] += val
        for kind in ("traction", "force"):
            for name, vec in getattr(ph, kind).items():
                fixed[params[(kind, name, "x")]] += vec[0]
                fixed[params[(kind, name, "y")]] += vec[1]
        if ph.gravity is not None:
            fixed[params[("gravity", "", "x")]] += ph.gravity[0]
            fixed[params[("gravity", "", "y")]] += ph.gravity[1]
        names = {v: k for k, v in params.items()}

        def describe(a: np.ndarray, names=names) -> dict:
            return {"parameters": {parameter_name(names[j]): float(a[j]) for j in range(len(a)) if a[j] != 0}}

        out.append(ProgramPhase(name=ph.name or f"phase {i}", steps=ph.steps, da=da, fixed=fixed,
                                normal_force=ph.until.normal_force if ph.until else None,
                                stop_at_gross_sliding=ph.stop_at_gross_sliding, describe=describe))
    return out


def _add_tractions(cfg: GmshBody, rec: ContactRecovery, states: list) -> None:
    """Each state's contact pressure ``p_N`` and tangential traction ``p_T`` per contact node [stress]
    (results.json ``contact_traction``), recovered from the nodal reactions (:class:`ContactRecovery`):
    the consistent recovery, and for P2 also the smooth vertex fit (``p_N_vertex_fit``)."""
    if not states or not np.all(np.diag(rec.M) > 0):
        return
    pN = rec.tractions(cfg.thickness, -np.array([s.r_N for s in states]))
    pT = rec.tractions(cfg.thickness, np.array([s.r_T for s in states]))
    for i, st in enumerate(states):
        out = {"p_N": [float(v) for v in pN["consistent"][i]], "p_T": [float(v) for v in pT["consistent"][i]],
               "recovery": f"consistent (P{cfg.degree} boundary mass matrix of the contact curve)"}
        if "vertex_fit" in pN:
            out.update(p_N_vertex_fit=[float(v) for v in pN["vertex_fit"][i]],
                       p_T_vertex_fit=[float(v) for v in pT["vertex_fit"][i]])
        st.extra["contact_traction"] = out


def path(scene, comm: MPI.Comm, stages: Stages, progress):
    """``(system, states, path_info)`` of a gmsh scene (MPI collective)."""
    from app.loading.program import ProgramError
    cfg: GmshBody = scene.system
    try:
        system = build(cfg, comm, stages, scene.units)
    except BodyError as err:          # a property of the body (its messages name their key)
        raise UnreachableLoad(str(err), key=None) from None
    n, limit = system.n_dofs, scene.settings.limits.max_dofs
    if n > limit:          # the size of a Gmsh body is known only once it is meshed (app/scene/limits.py)
        system.destroy()
        raise UnreachableLoad(f"system.file: the mesh has {n} DOFs, above settings.limits.max_dofs = {limit}; "
                              "use a coarser mesh or raise the limit", key=None)
    flex, given = system.flexibility, system.loading_input
    with stages("quasi-static loading"):
        try:
            solver, gaps = None, given.gaps
            if cfg.obstacle.curved:      # exact gaps and frames (app/loading/curved.py)
                from app.loading.curved import CurvedContact
                tvec, nvec = cfg.obstacle.frame()
                solver = CurvedContact(flex.schur, scene.mu, given.obstacle, given.contact_xy, tvec, nvec)
                gaps = np.zeros_like(gaps)
            states, info = run_program(_phases(cfg, given.params), given.U0, gaps,
                                       flex.schur, scene.mu, scene.settings.classify_rtol, progress, solver=solver)
        except ProgramError as err:
            system.destroy()
            raise UnreachableLoad(str(err)) from None
    info["initial_gaps"] = [float(g) for g in given.gaps]
    _add_tractions(cfg, given.recovery, states)
    from app.loading.sanity import check_body_path  # small-strain validity (warnings, never an error)
    tvec, nvec = cfg.obstacle.frame()
    # on a circle a state's u_N is minus its exact gap (app/loading/curved.py): no initial gap to add
    for w in check_body_path(states, system.fields.ops.size, tvec, nvec,
                             given.gaps if not cfg.obstacle.curved else None,
                             UNITS[scene.units]["length"]):
        log.warning("%s", w)
        stages.warnings.append(w)
    return system, states, info
