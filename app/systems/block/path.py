"""``system.type: block``: the block's System and its quasi-static loading path (docs/method.md section 5).

:func:`build` meshes the block (Gmsh), assembles K and M (DOLFINx), factorises K and computes the
contact flexibility W = B K^-1 B^T; :func:`path` runs the loading.

Phase 1 presses CD down in ``normal_steps`` equal increments to the displacement that makes the
normal resultant on AB equal ``normal_force``. The incremental problems are positively
homogeneous (zero initial gaps, no body force), so the whole phase scales linearly with the
final displacement: one trial path gives the exact factor, and the path is recomputed with it
(checked to 1e-8 relative). Phase 2 moves CD to the left by ``tangential_step`` per increment
until ``tangential_max``, or until gross sliding (every node in contact slips).
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from app.common.errors import UnreachableLoad
from app.common.progress import Progress
from app.common.stages import Stages
from app.loading.classify import FREE, SLIP, classified
from app.loading.contact import ContactSolveError, FrictionalContact
from app.loading.flexibility import contact_flexibility
from app.loading.state import EquilibriumState
from app.systems.base import ContactNode, System
from app.systems.block.schema import Block
from app.systems.units import CONTINUUM_UNITS as UNITS
from app.systems.units import implausible_material

log = logging.getLogger(__name__)


def build_block_system(cfg: Block, comm: MPI.Comm, stages: Stages, units: str = "mm-N-MPa-tonne-s"):
    """Mesh (Gmsh), operators (DOLFINx), factorisation and contact flexibility."""
    from app.systems.block.mesh import block_mesh
    from app.systems.block.operators import block_operators
    with stages("mesh (gmsh)"):
        mesh, facets = block_mesh(comm, cfg.length, cfg.height, cfg.nx, cfg.ny, cfg.pattern, cfg.mesh_size)
    with stages("assemble stiffness"):
        ops = block_operators(mesh, facets, cfg.E, cfg.nu, cfg.thickness, cfg.density, plane=cfg.plane,
                              degree=cfg.degree, mass_kind=cfg.mass, element=cfg.element)
    for w in implausible_material("system", cfg.E, cfg.density, units):
        log.warning("%s", w)
        stages.warnings.append(w)
    if cfg.degree == 1 and cfg.plane == "strain" and cfg.nu >= 0.45 and cfg.element == "displacement":
        log.warning("P1 triangles lock in plane strain as nu -> 0.5 (nu = %s): displacements, reactions "
                    "and mode shapes are too stiff; use degree: 2", cfg.nu)
        stages.warnings.append(f"volumetric locking: P1 triangles in plane strain with nu = {cfg.nu} "
                               f"are too stiff as nu -> 0.5; use degree: 2")
    n = len(ops.contact_x)
    if n == 0:
        raise UnreachableLoad("the mesh has no contact nodes on AB")
    # Paper axes: T = +x, N = outward normal of AB = -y.
    nodes = [ContactNode(id=i, x=float(ops.contact_x[i]), dof_T=int(ops.contact_dof_x[i]),
                         dof_N=int(ops.contact_dof_y[i]), sign_T=1, sign_N=-1) for i in range(n)]
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in nodes], dtype=float).ravel()
    with stages("factorise K, contact flexibility"):
        flex = contact_flexibility(ops.K, ops.load_x, ops.load_y, dofs, signs)
    system = System(comm=comm, K=ops.K, nodes=nodes, units=UNITS[units], stages=stages,
                    build_mass=lambda: ops.mass().copy(), build_contact_schur=lambda: flex.schur,
                    description=(f"block {cfg.length}x{cfg.height}x{cfg.thickness} {UNITS[units]['length']}, {cfg.nx}x{cfg.ny} "
                                 f"{cfg.pattern} {cfg.element_name()}, plane {cfg.plane}, E={cfg.E} {UNITS[units]['stress']}, nu={cfg.nu}, "
                                 f"{n} contact nodes, {ops.K.getSize()[0]} DOFs"))
    system.operators, system.flexibility = ops, flex
    system.static_dofs = ops.static
    system.static_constraint = ops.static is not None and cfg.nu == 0.5
    from app.systems.block.fields import BlockFields
    system.fields = BlockFields(cfg, ops, flex, nodes)
    return system, ops, flex


def build(cfg: Block, comm: MPI.Comm, stages: Stages, units: str = "mm-N-MPa-tonne-s") -> System:
    """The block's :class:`System` (MPI collective); its operators and flexibility are ``system.operators`` and ``system.flexibility``."""
    return build_block_system(cfg, comm, stages, units)[0]


def _state(index: int, phase: str, gx: float, gy: float, inc, extra: dict) -> EquilibriumState:
    load = {"phase": phase, "u_x": gx, "u_y": gy,
            "normal_resultant": float(-np.sum(inc.r_N)), "tangential_resultant": float(np.sum(inc.r_T))}
    return EquilibriumState(index=index, load=load, u_T=inc.u_T.copy(), u_N=inc.u_N.copy(),
                            r_T=inc.r_T.copy(), r_N=inc.r_N.copy(),
                            extra={"contact_solve": {"iterations": inc.iterations, "method": inc.method,
                                                     "violation": inc.violation}, **extra})


def path(scene, comm: MPI.Comm, stages: Stages, progress: Progress):
    """Build the block and run its loading; returns (system, states, path_info). The caller owns
    the system (``system.destroy()``); it is destroyed here if the loading fails."""
    system, walk = walker(scene, comm, stages)
    try:
        states, info = walk(progress)
    except BaseException:
        system.destroy()
        raise
    return system, states, info


def walker(scene, comm: MPI.Comm, stages: Stages):
    """Build the block (MPI collective) and return ``(system, walk)``: ``walk(progress,
    on_state=None) -> (states, path_info)`` runs the loading on this rank alone (dense work on
    the contact flexibility, no MPI), calling ``on_state(state)`` with each state as soon as it
    is known (app/study/stream.py sends them to the other ranks). The caller owns the system."""
    system, ops, flex = build_block_system(scene.system, comm, stages, scene.units)

    def walk(progress: Progress, on_state=None):
        return _loading(scene, flex, len(system.nodes), stages, progress, on_state or (lambda state: None))
    return system, walk


def _loading(scene, flex, n: int, stages: Stages, progress: Progress, on_state):
    """Press CD down, then drag it (the body of :func:`path`); returns (states, path_info)."""
    cfg: Block = scene.system
    ld = scene.loading
    with stages("quasi-static loading"), FrictionalContact(flex.schur, scene.mu) as solver:

        def press(depth: float, keep: bool):
            uT, g = np.zeros(n), np.zeros(n)
            out = []
            for k in range(1, ld.normal_steps + 1):
                gy = -depth * k / ld.normal_steps
                inc = solver.solve(flex.u0y * gy, uT, g)
                uT, g = inc.u_T, -inc.u_N
                if keep:
                    out.append((0.0, gy, inc))
            return inc, out

        # Trial depth from the fully bonded response, then the exact homogeneous rescaling.
        bonded = -np.sum((flex.schur @ flex.u0y)[1::2])  # normal resultant per mm of depth, AB bonded
        if not bonded > 0:
            raise UnreachableLoad("pressing CD down produces no compressive reaction on AB")
        depth = ld.normal_force / bonded
        for _ in range(4):
            inc, _ = press(depth, keep=False)
            fn = float(-np.sum(inc.r_N))
            if not fn > 0:
                raise UnreachableLoad(f"normal force {ld.normal_force} N cannot be reached: the path gives {fn} N")
            depth *= ld.normal_force / fn
            inc, phase1 = press(depth, keep=True)
            fn = float(-np.sum(inc.r_N))
            if abs(fn - ld.normal_force) <= 1e-10 * ld.normal_force:
                break
        states = [_state(i, "normal", gx, gy, r, {}) for i, (gx, gy, r) in enumerate(phase1)]
        for st in states:
            on_state(st)
        uT, g = phase1[-1][2].u_T, -phase1[-1][2].u_N
        gy = -depth
        failure = None
        end = f"tangential_max = {ld.tangential_max} {UNITS[scene.units]['length']} reached"
        nsteps = int(np.floor(ld.tangential_max / ld.tangential_step + 1e-9))
        bar = progress.bar(nsteps, "loading")
        d = None                  # each drag increment starts from the previous one's slip
        for k in range(1, nsteps + 1):
            gx = -ld.tangential_step * k
            try:
                inc = solver.solve(flex.u0x * gx + flex.u0y * gy, uT, g, d)
            except ContactSolveError as err:
                end = f"contact solve failed at CD u_x = {gx}: {err}"
                failure = {"state": len(states), "analysis": "contact increment", "reason": end}
                break
            uT, g, d = inc.u_T, -inc.u_N, inc.slip_increment
            st = _state(len(states), "tangential", gx, gy, inc, {})
            states.append(st)
            on_state(st)
            bar.update(1)
            cls = classified(st, scene.mu, scene.settings.classify_rtol)
            contact = [s for s in cls.status if s not in (FREE,)]
            if contact and all(s == SLIP for s in contact):
                end = (f"gross sliding at CD u_x = {gx:.6g} {UNITS[scene.units]['length']}: all {len(contact)} nodes in contact slip "
                       f"(tangential resultant = mu x normal resultant)")
                break
        bar.close()
    from app.loading.sanity import check_block_path  # small-strain validity (warnings, never an error)
    for w in check_block_path(states, cfg.length, cfg.height, UNITS[scene.units]["length"]):
        log.warning("%s", w)
        stages.warnings.append(w)
    # in the scene's units (results.json ``units``): length, force
    info = {"end": end, "normal_displacement": depth, "normal_force": float(-np.sum(states[ld.normal_steps - 1].r_N)),
            "normal_steps": ld.normal_steps, "tangential_step": ld.tangential_step, "failure": failure}
    return states, info
