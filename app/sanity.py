"""Physical sanity of a loading path: is small-strain linear elasticity still valid?

The app's model is linear elasticity with small strains (DESIGN.md section 1). A path whose
displacements are comparable to the body, or whose nominal strains exceed a few percent, is
outside that model: its numbers are not physics. A unit mistake (E in Pa with lengths in mm, a
force 100 times too large) shows up here. The checks use the prescribed motion of CD and the
contact displacements of every state, so they cost nothing:

- nominal normal strain ``|u_y(CD)| / H`` (CD pressed into the block) and nominal shear strain
  ``|u_x(CD) - mean u_T(AB)| / H`` (CD dragged relative to the contact face); displacements
  comparable to the body show up here (a rigid translation, as in gross sliding, is no strain);
- penetration ``max u_N > 0`` (paper sign: ``u_N <= 0`` means no penetration) relative to the
  body's smaller side.

The strain limit is 10 %: the paper's own block study reaches a mean nominal shear strain of
8.3 % at gross sliding (local strains near the stick/slip front are larger), so a stricter
limit would flag the reference study itself.

Each violated check gives one warning naming the first state, the worst state and by how much.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from app.loading.state import EquilibriumState

STRAIN_LIMIT = 0.10          # beyond this nominal strain, small-strain elasticity is clearly invalid
PENETRATION_LIMIT = 0.01     # penetration as a fraction of the body's smaller side


def _pct(x: float) -> str:
    return "inf %" if not math.isfinite(x) else f"{100 * x:.3g} %"


def _report(what: str, values: Sequence[float], limit: float, states: Sequence[EquilibriumState],
            detail) -> str | None:
    vals = np.array([v if math.isfinite(v) else math.inf for v in values])
    bad = np.flatnonzero(~(vals <= limit))
    if bad.size == 0:
        return None
    first, worst = int(bad[0]), int(np.argmax(np.where(np.isfinite(vals), vals, np.inf)))
    return (f"small-strain assumption violated: {what} above {_pct(limit)} from state {states[first].index} "
            f"({detail(first)}) to a worst {_pct(vals[worst])} at state {states[worst].index} ({detail(worst)}); "
            f"linear elasticity is not valid there (check E, the loads and the units)")


def check_block_path(states: Sequence[EquilibriumState], length: float, height: float,
                     unit: str = "mm") -> list[str]:
    """Warnings (possibly none) for the block's loading path; see the module docstring."""
    if not states:
        return []
    size = min(length, height)
    out = []
    normal, shear, pen = [], [], []
    for st in states:
        gx, gy = float(st.load.get("u_x", 0.0)), float(st.load.get("u_y", 0.0))
        normal.append(abs(gy) / height)
        shear.append(abs(gx - float(np.mean(st.u_T))) / height if len(st.u_T) else 0.0)
        pen.append(max(float(np.max(st.u_N, initial=0.0)), 0.0) / size)
    nonfinite = [st.index for st in states
                 if not all(np.all(np.isfinite(a)) for a in (st.u_T, st.u_N, st.r_T, st.r_N))]
    if nonfinite:
        out.append(f"non-finite displacements or reactions (overflow of double precision) at {len(nonfinite)} "
                   f"state(s), first state {nonfinite[0]}: the scene's sizes, E or loads are out of range "
                   f"(check the units)")
    g = lambda i: states[i].load  # noqa: E731
    checks = [
        ("nominal normal strain (CD pressed in / height)", normal, STRAIN_LIMIT,
         lambda i: f"CD pressed {abs(g(i).get('u_y', 0.0)):.4g} {unit} into a {height:.4g} {unit} high block"),
        ("nominal shear strain (CD motion relative to AB / height)", shear, STRAIN_LIMIT,
         lambda i: f"CD u_x = {g(i).get('u_x', 0.0):.4g} {unit} on a {height:.4g} {unit} high block"),
        ("penetration into the obstacle / body size", pen, PENETRATION_LIMIT,
         lambda i: f"max u_N = {pen[i] * size:.4g} {unit}"),
    ]
    for what, vals, limit, detail in checks:
        msg = _report(what, vals, limit, states, detail)
        if msg:
            out.append(msg)
    return out
