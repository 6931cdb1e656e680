"""Physical sanity of a loading path: whether small-strain linear elasticity still holds.

The app's model is linear elasticity with small strains (docs/method.md section 1). A path whose
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

:func:`check_contact` looks at the classified path of any system type: a body that never touches
the obstacle, a path that slides grossly at its first step of loading, and a path without a
single slip node, on which the MCEIPs have no unknowns (their "no solution" holds trivially).
:func:`check_final_stick_zone` looks at a meshed body's final state: a stick zone one node wide,
which the mesh does not resolve, makes that state's critical mu depend on the mesh.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from app.loading.classify import FREE, SLIP, Classification, without_point_stick
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
    first = int(bad[0])
    # the first state that reaches the largest value to within rounding: states held at the same
    # load differ in the last bits only, and which of them is larger is no answer
    top = float(np.max(vals))
    worst = int(np.flatnonzero(vals >= top * (1.0 - 1e-9))[0]) if math.isfinite(top) else int(np.argmax(vals))
    return (f"small-strain assumption violated: {what} above {_pct(limit)} from state {states[first].index} "
            f"({detail(first)}) to a worst {_pct(vals[worst])} at state {states[worst].index} ({detail(worst)}); "
            f"linear elasticity is not valid there (check E, the loads and the units)")


def _reports(checks: list, states: Sequence[EquilibriumState]) -> list[str]:
    """The warnings of the violated ``(what, values, limit, detail)`` checks."""
    return [m for what, vals, limit, detail in checks if (m := _report(what, vals, limit, states, detail))]


def check_finite(states: Sequence[EquilibriumState]) -> list[str]:
    """A warning if some state's contact displacements or reactions are not finite (any system type)."""
    nonfinite = [st.index for st in states
                 if not all(np.all(np.isfinite(a)) for a in (st.u_T, st.u_N, st.r_T, st.r_N))]
    if not nonfinite:
        return []
    return [f"non-finite displacements or reactions (overflow of double precision) at {len(nonfinite)} "
            f"state(s), first state {nonfinite[0]}: the scene's sizes, E or loads are out of range (check the units)"]


def check_body_path(states: Sequence[EquilibriumState], size: float, tangent, normal, gaps=None,
                    unit: str = "mm") -> list[str]:
    """Warnings for a meshed body of any shape (``system.type: gmsh``): finiteness; the nominal strain of
    every prescribed curve's motion relative to the mean contact displacement, and the spread of the
    contact displacements, over the body's size ``size``; the linearised rotations (above 0.1 rad
    a rotation is not small); the penetration into the obstacle. ``tangent``/``normal``: the
    obstacle's unit vectors (contact displacements are along them); ``gaps``: the initial gaps
    (a state's ``u_N`` is its normal displacement minus the gap)."""
    if not states:
        return []
    out = check_finite(states)
    t, n = np.asarray(tangent, dtype=float), np.asarray(normal, dtype=float)
    g = np.zeros(len(states[0].u_N)) if gaps is None else np.asarray(gaps, dtype=float)
    strain, spread, rotation, pen = [], [], [], []
    for st in states:
        params = st.load.get("parameters", {})
        uc = (float(np.mean(st.u_T)) * t + float(np.mean(st.u_N + g)) * n) if len(st.u_T) else np.zeros(2)
        worst, rot = 0.0, 0.0
        for key, v in params.items():
            if key.startswith("motion.") and key.endswith(".tx"):
                d = np.array([v, params.get(key[:-3] + ".ty", 0.0)])
                worst = max(worst, float(np.hypot(*(d - uc))) / size)
            elif key.startswith("motion.") and key.endswith(".ty") and key[:-3] + ".tx" not in params:
                worst = max(worst, float(np.hypot(*(np.array([0.0, v]) - uc))) / size)
            elif key.startswith("motion.") and key.endswith(".rz"):
                rot = max(rot, abs(float(v)))
        strain.append(worst)
        rotation.append(rot)
        spread.append(float(np.ptp(st.u_T)) / size if len(st.u_T) else 0.0)
        pen.append(max(float(np.max(st.u_N, initial=0.0)), 0.0) / size)
    checks = [
        ("nominal strain (prescribed motion relative to the contact curve / body size)", strain, STRAIN_LIMIT,
         lambda i: f"{strain[i] * size:.4g} {unit} on a {size:.4g} {unit} body"),
        ("spread of the tangential contact displacements / body size", spread, STRAIN_LIMIT,
         lambda i: f"{spread[i] * size:.4g} {unit}"),
        ("linearised rotation of a prescribed curve [rad]", rotation, STRAIN_LIMIT,
         lambda i: f"{rotation[i]:.4g} rad"),
        ("penetration into the obstacle / body size", pen, PENETRATION_LIMIT,
         lambda i: f"max u_N = {pen[i] * size:.4g} {unit}"),
    ]
    return out + _reports(checks, states)


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
    out.extend(check_finite(states))
    g = lambda i: states[i].load  # noqa: E731
    checks = [
        ("nominal normal strain (CD pressed in / height)", normal, STRAIN_LIMIT,
         lambda i: f"CD pressed {abs(g(i).get('u_y', 0.0)):.4g} {unit} into a {height:.4g} {unit} high block"),
        ("nominal shear strain (CD motion relative to AB / height)", shear, STRAIN_LIMIT,
         lambda i: f"CD u_x = {g(i).get('u_x', 0.0):.4g} {unit} on a {height:.4g} {unit} high block"),
        ("penetration into the obstacle / body size", pen, PENETRATION_LIMIT,
         lambda i: f"max u_N = {pen[i] * size:.4g} {unit}"),
    ]
    return out + _reports(checks, states)


def check_contact(states: Sequence[EquilibriumState], classes: Sequence[Classification], end: str,
                  mceip: bool) -> list[str]:
    """Warnings for a classified path that makes the analyses meaningless: no contact node in
    contact at any state; gross sliding (``end``: the path's end in words) at the first step of
    a phase (of the tangential loading for the block), as when E or the loads are off by orders of
    magnitude; no slip node at any state while an MCEIP is asked for (``mceip``)."""
    out = []
    if not states:
        return out
    if all(all(st == FREE for st in c.status) for c in classes):
        out.append(f"no contact node touches the obstacle in any of the {len(states)} states: there is no "
                   "contact to analyse (check the obstacle's position and the loading)")
    elif mceip and not any(SLIP in c.status for c in classes):
        out.append(f"no contact node slips in any of the {len(states)} states: MCEIP-mu and MCEIP-lambda^2 have "
                   "no unknowns, so their 'no solution' holds trivially (nothing was proven about slip)")
    phase = [st.load.get("phase") for st in states]
    if end.startswith("gross sliding") and (len(states) == 1 or phase[-1] != phase[-2]):
        out.append(f"gross sliding at the first loading step of its phase (state {states[-1].index}, "
                   f"phase {phase[-1]!r}): the whole contact slipped at once, so the path has no state of "
                   "partial slip to analyse (check E, mu, the loads and the units, or take smaller steps)")
    return out


def check_final_stick_zone(cls: Classification, x: Sequence[float], index: int, unit: str = "mm") -> list[str]:
    """A warning when the final state ``cls`` (state ``index``; ``x``: the contact nodes'
    coordinates along the contact curve) has a stick zone one node wide
    (:func:`app.loading.classify.without_point_stick`). Such a node stands for a zone the mesh does
    not resolve: while the mesh is coarser than the zone, the stiffness it adds falls like
    ``1 / ln(L / h)``, and so does the critical mu of the state (the paper's block in plane strain
    at nu = 0.48: 2.42 at 10 x 5 to 1.72 at 160 x 80, 1.770 on meshes graded towards the zone;
    docs/validation.md)."""
    point = without_point_stick(cls, x)
    if point is None:
        return []
    nodes = [i for i, (a, b) in enumerate(zip(cls.status, point.status)) if a != b]
    where = ", ".join(f"{x[i]:.4g}" for i in nodes[:5]) + (", ..." if len(nodes) > 5 else "")
    return [f"the final state (state {index}) has {len(nodes)} stick zone(s) one node wide, at x = {where} {unit} "
            "along the contact curve: the mesh does not resolve them, and the critical mu of that state depends "
            "on the mesh there (like 1 / ln(L / h)); refine the mesh towards them until each zone spans several "
            "nodes (docs/limitations.md, 'Stick zones narrower than the mesh')"]
