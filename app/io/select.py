"""Which states the scene's ``outputs.states`` selects, from the results alone.

The same function runs inside the study (to know which fields to compute) and in
``python -m app render`` (to redraw them), so both agree.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from app.io.result import Analyses, MceipSolution, StateResult

MODE_PROBLEMS = (("sufficient", "sufficient"), ("mceip_mu", "mceip_mu"), ("mceip_lambda2", "mceip_lambda2"))


def _plain(sel):
    """A selector as plain data (the pydantic model or its JSON dump)."""
    if hasattr(sel, "model_dump"):
        sel = sel.model_dump()
    if isinstance(sel, dict):
        sel = {k: v for k, v in sel.items() if v is not None}
    return sel


def describe(sel) -> str:
    """The selector of ``outputs.states`` in words, e.g. "state 3", "final state" or "first state
    with 2 slip"."""
    sel = _plain(sel)
    if isinstance(sel, dict):
        return "first state with " + ", ".join(f"{v} {k}" for k, v in sel.items())
    if isinstance(sel, int):
        return f"state {sel}"
    return {"final": "final state", "first_mceip_mu": "first state with an MCEIP-mu solution",
            "all_distinct": "first state of every distinct classification"}.get(sel, str(sel))


def select_states(states: Sequence[StateResult], selectors) -> tuple[list[int], list[str]]:
    """State indices chosen by ``selectors`` (sorted, unique) and a note for each selector that
    chose nothing."""
    by_index = {s.index: s for s in states}
    chosen: list[int] = []
    notes: list[str] = []
    for raw in selectors:
        sel = _plain(raw)
        found: list[int] = []
        if isinstance(sel, int):
            found = [sel] if sel in by_index else []
        elif sel == "final":
            found = [states[-1].index] if states else []
        elif sel == "first_mceip_mu":
            found = [s.index for s in states if s.mceip_mu is not None and s.mceip_mu.solutions][:1]
        elif sel == "all_distinct":
            found = [s.index for s in states if s.analyses_shared_with is None]
        elif isinstance(sel, dict):
            found = [s.index for s in states
                     if all(getattr(s.classification, k, None) == v for k, v in sel.items())][:1]
        if not found:
            notes.append(f"outputs.states: {describe(sel)}: no such state in this study "
                         f"({len(states)} states, indices 0 to {len(states) - 1})")
        chosen += found
    return sorted(set(chosen)), notes


def analyses_of(states: Sequence[StateResult], index: int) -> tuple[Analyses, int]:
    """The analyses of state ``index`` and the index of the state they were computed at."""
    st = next(s for s in states if s.index == index)
    first = st.analyses_shared_with
    return st.analyses, index if first is None else first


def modes_of(analyses: Analyses) -> list[tuple[str, int, MceipSolution]]:
    """Every divergence mode of one state's analyses: (problem, number, solution).

    problem is ``sufficient`` (eigenpairs of (17)-(18)), ``mceip_mu`` or ``mceip_lambda2``.
    """
    out = []
    for key, problem in MODE_PROBLEMS:
        a = getattr(analyses, key)
        if a is None or not a.answered:
            continue
        sols = a.modes if key == "sufficient" else a.solutions
        for k, sol in enumerate(sols):
            out.append((problem, k, sol))
    return out


def mode_name(first: int, problem: str, k: int, value: float) -> str:
    """Field name of a mode: its state, problem, number and eigenvalue, e.g. ``s0237_mceip_mu_0_60.8058``."""
    return f"s{first:04d}_{problem}_{k}_{value:.6g}"


def _unit(units, key: str) -> str | None:
    """A unit name of the study's ``units`` (the typed :class:`~app.io.result.Units` or its dict)."""
    return units.get(key) if isinstance(units, dict) else getattr(units, key, None)


def parameter_unit(name: str, units) -> str | None:
    """The unit of a loading program's load parameter named as results.json's ``load.parameters``
    names it (app/systems/gmsh/fields.py ``parameter_name``): ``motion.<curve>.tx``/``ty`` a
    length, ``motion.<curve>.rz`` radians, ``traction.<curve>.x``/``y`` a stress,
    ``force.<curve>.x``/``y`` a force, ``gravity.x``/``y`` an acceleration; None if unknown."""
    kind, _, comp = name.partition(".")
    comp = comp.rpartition(".")[2]
    length, time = _unit(units, "length"), _unit(units, "time") or "s"
    if kind == "motion":
        return "rad" if comp == "rz" else length
    return {"traction": _unit(units, "stress"), "force": _unit(units, "force"),
            "gravity": f"{length}/{time}^2"}.get(kind)


def _program_axis(states: Sequence[StateResult], units) -> tuple[np.ndarray, str] | None:
    """:func:`program_load` of the states' load parameters."""
    return program_load([s.load.parameters if s.load is not None else None for s in states], units)


def program_load(parameters: Sequence[dict | None], units) -> tuple[np.ndarray, str] | None:
    """A loading program's load parameters (one dict per state, results.json's
    ``load.parameters``) as one axis ``(x, label)``: when every parameter the program moves has
    the same unit, the distance the parameters travel (Euclidean, summed over the steps, from the
    unloaded start), strictly increasing; None otherwise."""
    params = [None if p is None else dict(p) for p in parameters]
    if not params or any(p is None for p in params):
        return None
    names = sorted({n for p in params for n in p})
    found = {parameter_unit(n, units) for n in names}
    if not names or len(found) != 1 or None in found:
        return None
    unit = found.pop()
    a = np.array([[0.0] * len(names)] + [[float(p.get(n, 0.0)) for n in names] for p in params])
    if not np.all(np.isfinite(a)):
        return None
    x = np.cumsum(np.linalg.norm(np.diff(a, axis=0), axis=1))
    if not np.all(np.diff(x) > 0) or x[0] <= 0:
        return None
    kinds = sorted({n.split(".")[0] for n in names})
    curves = sorted({n.split(".")[1] for n in names if n.count(".") == 2})
    on = f" of {', '.join(curves[:3])}{', ...' if len(curves) > 3 else ''}" if curves else ""
    what = {"motion": "prescribed motion", "traction": "applied traction", "force": "applied force",
            "gravity": "body acceleration"}.get(kinds[0], kinds[0]) if len(kinds) == 1 else "load parameters"
    return x, f"{what}{on}, travelled along the program [{unit}]"


def load_axis(states: Sequence[StateResult], units) -> tuple[np.ndarray, str, bool]:
    """Where each state sits along the loading: ``(x of each state, label, is_load)``, in the units
    of ``units`` (the study's :class:`~app.io.result.Units` or its dict). For a loading given by
    the motion of CD (the block: ``u_x``, ``u_y`` at every state) the distance CD has travelled
    along the path, pressed then dragged; for a loading program whose parameters share one unit
    (motions, or forces, ...) the distance its parameters travel; both strictly increasing, so
    every state has its place (the plots' x-axis, ParaView's time). Otherwise the state index."""
    length = _unit(units, "length")
    loads = [(s.load.u_x, s.load.u_y) for s in states]
    if states and all(ux is not None and uy is not None and np.isfinite(ux) and np.isfinite(uy) for ux, uy in loads):
        u = np.array([(0.0, 0.0), *loads], dtype=float)
        x = np.cumsum(np.hypot(*np.diff(u, axis=0).T))
        if np.all(np.diff(x) > 0):
            return x, f"distance travelled by CD, pressed then dragged [{length}]", True
    program = _program_axis(states, units)
    if program is not None:
        return program[0], program[1], True
    return np.array([s.index for s in states], dtype=float), "load step (state index)", False


#: frames of a mode's animation (GIF and ParaView series), and the amplitude its growth starts from
#: (a fraction of the largest one)
FRAMES = 16
START = 0.05


def mode_growth(problem: str, value: float) -> list[tuple[float | None, float]]:
    """The frames of a mode growing as the divergence it predicts, ``u0 + a(t) v``: ``(t, a)`` with
    ``a(t) = a0 exp(lambda t)`` for a mode with ``lambda^2 = value > 0`` (MCEIP-lambda^2, the
    sufficient condition; the paper's eq. (8)), from :data:`START` of the largest amplitude to all
    of it over ``t = ln(1 / START) / lambda`` (``t`` in the time unit); for MCEIP-mu's static mode
    (``lambda = 0``, the transition) ``t`` is None and ``a`` grows linearly."""
    lam2 = float(value) if problem != "mceip_mu" else 0.0
    lam = float(np.sqrt(lam2)) if lam2 > 0 else 0.0
    out: list[tuple[float | None, float]] = []
    for k in range(FRAMES):
        f = k / (FRAMES - 1)
        if lam > 0:
            t = f * float(np.log(1.0 / START)) / lam
            out.append((t, START * float(np.exp(lam * t))))
        else:
            out.append((None, max(f, START)))
    return out
