"""Loading programs: phases of prescribed motions and applied loads, solved increment by increment.

A system with ``P`` load parameters ``a`` (translations and rotations of prescribed curves, force
and traction components, gravity components) responds linearly with zero contact reactions: the
contact displacements are ``u0(a) = U0 a`` (paper axes, columns from one solve each). A phase adds
``da`` in ``steps`` equal increments, starting from the end of the previous phase; each increment
is the frictional contact problem (app/loading/contact.py, paper eqs. (1)-(2)) with the initial
gaps ``g0`` entering as a shift of ``u0`` (``u_N <= g0``).

Force control of a displacement phase (``until: normal_force F``): the phase's motions ``da`` are
scaled by ``c`` so that the normal resultant ``-sum r_N`` is F at its end; the loads of the same
phase (``fixed``: forces, tractions, gravity) are applied as given. When the phase starts from the
unloaded state with zero gaps and no loads (in it or before), every increment is positively homogeneous in ``c``
(docs/method.md section 5): one trial run gives the exact factor, as for the built-in block
(app/systems/block/path.py), and the same two runs are made here. Otherwise ``c`` is bracketed
(doubled until the force is passed, e.g. to close gaps) and found by regula falsi (Illinois); either way the reached force is checked to 1e-10 relative.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from app.loading.classify import FREE, SLIP, classified
from app.loading.contact import ContactSolveError, FrictionalContact
from app.loading.state import EquilibriumState


class ProgramError(Exception):
    """A phase cannot do what it asks (e.g. an unreachable normal force): one-line message."""


@dataclass
class ProgramPhase:
    """A phase in parameter form: increment ``da`` of the load parameters in ``steps`` steps."""

    name: str
    steps: int
    da: np.ndarray                        # the increment (with ``normal_force``: the part it scales, the motions)
    normal_force: Optional[float] = None
    stop_at_gross_sliding: bool = True
    describe: Callable[[np.ndarray], dict] = field(default=lambda a: {})
    fixed: Optional[np.ndarray] = None    # the part of the increment ``normal_force`` does not scale (loads)

    def increment(self, c: float = 1.0) -> np.ndarray:
        """The phase's whole increment when its scaled part is multiplied by ``c``."""
        return c * self.da if self.fixed is None else self.fixed + c * self.da


def _run_phase(solver: FrictionalContact, U0: np.ndarray, G: np.ndarray, a0: np.ndarray, da: np.ndarray,
               steps: int, u_prev: np.ndarray):
    """Increments of one phase; yields (k, a, IncrementResult)."""
    for k in range(1, steps + 1):
        a = a0 + da * (k / steps)
        u0 = U0 @ a - G
        inc = solver.solve(u0, u_prev[0::2], -u_prev[1::2])
        # a curved obstacle's solver continues from the displacements in the system frames
        u_prev = solver.carry(inc) if hasattr(solver, "carry") else np.ravel(np.column_stack([inc.u_T, inc.u_N]))
        # Reactions at the round-off level of r = Kc (u_c - u0) are zero (e.g. before a gap closes):
        # the classification's tolerances are relative to the state's own reactions.
        noise = 1e-12 * solver.kscale * max(float(np.max(np.abs(u0))), float(np.max(np.abs(u_prev))))
        for r in (inc.r_N, inc.r_T):
            r[np.abs(r) <= noise] = 0.0
        yield k, a, inc, u_prev


def _end_force(solver, U0, G, a0, da, steps, u_prev) -> float:
    inc = None
    for _, _, inc, _ in _run_phase(solver, U0, G, a0, da, steps, u_prev):
        pass
    return float(-np.sum(inc.r_N))


def _scale_for_force(solver, U0, G, a0, ph: ProgramPhase, u_prev, homogeneous: bool) -> float:
    """Factor c such that the phase with c * da ends at the normal resultant ph.normal_force."""
    F = ph.normal_force
    bonded = np.sum(((solver.Kc * solver.kscale) @ (U0 @ ph.da))[1::2])   # -sum r_N per unit c, contact bonded
    if not bonded > 0:
        raise ProgramError(f"phase '{ph.name}': its prescribed motion produces no compressive reaction on the "
                           "contact curve, so the normal force cannot be reached")
    c = F / bonded
    if homogeneous:
        for _ in range(4):          # the block's recipe: exact after one rescaling (homogeneity)
            fn = _end_force(solver, U0, G, a0, ph.increment(c), ph.steps, u_prev)
            if not fn > 0:
                raise ProgramError(f"phase '{ph.name}': normal force {F} cannot be reached (the path gives {fn})")
            c *= F / fn
            if abs(_end_force(solver, U0, G, a0, ph.increment(c), ph.steps, u_prev) - F) <= 1e-10 * F:
                return c
    else:                            # bracket, then regula falsi (Illinois) on f(c) = resultant(c) - F
        def f(c: float) -> float:
            return _end_force(solver, U0, G, a0, ph.increment(c), ph.steps, u_prev) - F
        lo, f_lo = 0.0, f(0.0)
        if f_lo >= 0:
            raise ProgramError(f"phase '{ph.name}': the normal resultant already reaches {F} without this phase's motion")
        hi, f_hi = c, f(c)
        for _ in range(60):          # a gap to close: grow the motion until the force is passed
            if f_hi >= 0:
                break
            lo, f_lo, hi = hi, f_hi, 2.0 * hi
            f_hi = f(hi)
        else:
            raise ProgramError(f"phase '{ph.name}': normal force {F} not reached by 2^60 times the bonded estimate")
        side = 0
        for _ in range(200):
            c = hi - f_hi * (hi - lo) / (f_hi - f_lo)
            fc = f(c)
            if abs(fc) <= 1e-10 * F:
                return c
            if fc > 0:
                hi, f_hi = c, fc
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                lo, f_lo = c, fc
                if side == -1:
                    f_hi *= 0.5
                side = -1
    raise ProgramError(f"phase '{ph.name}': normal force {F} not reached to 1e-10 relative")


def run_program(phases: list[ProgramPhase], U0: np.ndarray, gaps: np.ndarray, Kc: np.ndarray, mu: float,
                classify_rtol: float, progress, solver=None):
    """Equilibrium states of the whole program; returns (states, path_info).

    ``solver``: the increment solver of a curved obstacle (app/loading/curved.py: it owns the
    gaps, so ``gaps`` are zero, and no increment is positively homogeneous); default the flat one."""
    n = U0.shape[0] // 2
    G = np.zeros(2 * n)
    G[1::2] = gaps
    curved = solver is not None
    solver = FrictionalContact(Kc, mu) if solver is None else solver
    states: list[EquilibriumState] = []
    info: dict = {"phases": [], "failure": None}
    a = np.zeros(U0.shape[1])
    u_prev = np.zeros(2 * n)
    end = "all phases applied"
    try:
        bar = progress.bar(sum(p.steps for p in phases), "loading")
        for i, ph in enumerate(phases):
            da = ph.increment()
            rec = {"name": ph.name, "steps": ph.steps}
            if ph.normal_force is not None:
                homogeneous = (not curved and not np.any(a) and not np.any(gaps) and not np.any(u_prev)
                               and (ph.fixed is None or not np.any(ph.fixed)))
                c = _scale_for_force(solver, U0, G, a, ph, u_prev, homogeneous)
                da = ph.increment(c)
                rec.update(scale=c, normal_force=ph.normal_force, homogeneous=homogeneous)
            stop = None
            try:
                for k, ak, inc, u_prev in _run_phase(solver, U0, G, a, da, ph.steps, u_prev):
                    load = {"phase": i, "name": ph.name, "step": k, **ph.describe(ak),
                            "normal_resultant": float(-np.sum(inc.r_N)),
                            "tangential_resultant": float(np.sum(inc.r_T))}
                    st = EquilibriumState(index=len(states), load=load, u_T=inc.u_T.copy(), u_N=inc.u_N.copy(),
                                          r_T=inc.r_T.copy(), r_N=inc.r_N.copy(),
                                          extra={"contact_solve": {"iterations": inc.iterations, "method": inc.method,
                                                                   "violation": inc.violation},
                                                 **({"curved_contact": inc.extra["curved_contact"]}
                                                    if inc.extra and "curved_contact" in inc.extra else {})})
                    states.append(st)
                    bar.update(1)
                    if ph.stop_at_gross_sliding and mu > 0:     # frictionless: "slip" is every contact
                        cls = classified(st, mu, classify_rtol)
                        contact = [s for s in cls.status if s != FREE]
                        if contact and all(s == SLIP for s in contact):
                            stop = (f"gross sliding in {_phase(i, ph)} at step {k}: all {len(contact)} "
                                    "nodes in contact slip")
                            break
                    if k == ph.steps:
                        a = ak
            except ContactSolveError as err:
                end = f"contact solve failed in {_phase(i, ph)}: {err}"
                info["failure"] = {"state": len(states), "analysis": "contact increment", "reason": end}
                info["phases"].append(rec)
                break
            info["phases"].append(rec)
            if stop:
                end = stop
                break
        bar.close()
    finally:
        solver.destroy()
    info["end"] = end
    return states, info


def _phase(i: int, ph) -> str:
    """A phase in words: its name where it has one (``the 'drag' phase``), else its number as
    results.json's ``load.phase`` counts it (``phase 1``)."""
    return f"the '{ph.name}' phase" if ph.name else f"phase {i}"
