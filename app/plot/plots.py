"""Plots of a study (matplotlib, PNG and SVG), drawn from the typed results
([`StudyResult`][app.io.result.StudyResult]) alone.

* ``status_map``: the status of every contact node (free, zero, stick, slip) against the load
  step: how slip spreads along AB;
* ``reactions``: normal and tangential reactions along AB at the pictured states, with the
  Coulomb limits +-mu |r_N|;
* ``mceip_mu``: the smallest MCEIP-mu value (every value as dots) and the number of slip nodes
  against the load step, with the scene's mu;
* ``necessary``: the smallest eigenvalue of sym K*(mu) (necessary condition (19)) against the
  load step: the condition holds where it is <= 0.
"""
from __future__ import annotations

import math
import pathlib
from typing import Sequence

import numpy as np

from app.io.result import StateResult, StudyResult
from app.io.select import load_axis

STATUS_ORDER = ("free", "zero", "stick", "slip")
#: space between a plot along the loading and its title, for the phase labels (points)
TITLE_PAD = 14
STATUS_COLOURS = {"free": "#d9d9d9", "zero": "#9467bd", "stick": "#1f77b4", "slip": "#d62728"}


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _num(v) -> float:
    """A number of the results as a float (``None``, no number: NaN)."""
    return math.nan if v is None else float(v)


def _save(fig, path: pathlib.Path) -> list[pathlib.Path]:
    """The figure as PNG (150 dpi) and SVG, both cropped to the tight box of the PNG's layout.

    The tight box is computed once (``bbox_inches="tight"`` lays the figure out once more per
    file: 4 layouts instead of 2 for the two files)."""
    import matplotlib
    path.parent.mkdir(parents=True, exist_ok=True)
    dpi = fig.dpi
    fig.dpi = 150                                  # the PNG's resolution, as savefig(dpi=150) sets it
    try:
        renderer = fig.canvas.get_renderer()
        fig.draw_without_rendering()               # final layout (ticks, colour bars, twin axes)
        box = fig.get_tightbbox(renderer).padded(matplotlib.rcParams["savefig.pad_inches"])
    finally:
        fig.dpi = dpi
    out = []
    for ext in ("png", "svg"):
        p = path.with_suffix("." + ext)
        fig.savefig(p, dpi=150 if ext == "png" else None, bbox_inches=box)
        out.append(p)
    _plt().close(fig)
    return out


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres ``x`` (halfway between neighbours)."""
    if len(x) == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])


def _mark_phases(ax, states: Sequence[StateResult], x: np.ndarray) -> None:
    """The block's tangential loading, or where each phase of a loading program after the first
    starts (a program numbers its phases and names them in the load's ``name``), at the edge
    before the phase's first state (``x``: the states' positions on the axis)."""
    edges = _edges(x)
    t0 = next((k for k, s in enumerate(states) if s.load.phase == "tangential"), None)
    starts = [(t0, "tangential loading")] if t0 is not None else []
    prev = None
    for k, s in enumerate(states) if t0 is None else ():
        ph = s.load.phase
        if isinstance(ph, int) and prev is not None and ph != prev:
            starts.append((k, (s.load.model_extra or {}).get("name") or f"phase {ph}"))
        prev = ph
    # the labels sit just above the frame, under the title (:data:`TITLE_PAD`), clear of the data
    for k, label in starts:
        ax.axvline(edges[k], color="0.4", lw=0.8, ls=":")
        ax.annotate(f"{label} \u2192", (edges[k], 1.0), xycoords=("data", "axes fraction"),
                    xytext=(0, 2), textcoords="offset points", va="bottom", ha="left", fontsize=8, color="0.3")


def _isolated(y: np.ndarray) -> np.ndarray:
    """Where ``y`` is finite but both neighbours are not: a step line (``steps-mid``) draws nothing
    there, so these values are drawn as markers."""
    f = np.isfinite(y)
    prev = np.concatenate([[False], f[:-1]])
    nxt = np.concatenate([f[1:], [False]])
    return f & ~prev & ~nxt


def _along(study: StudyResult) -> str:
    """"along the loading", or "at its only state" for a study of one state (two particles, matrices)."""
    return "at its only state" if len(study.states) == 1 else "along the loading"


def _title(study: StudyResult, what: str) -> str:
    return f"{study.scene}: {what}"


def _system_type(study: StudyResult):
    """The registered system type of the study (app/systems/, from its scene), None if unknown."""
    from app.systems import SYSTEM_TYPES
    return SYSTEM_TYPES.get((study.scene_config.get("system") or {}).get("type", "block"))


def _contact_line(study: StudyResult) -> str | None:
    """Name of the contact side (the block's AB), None when the system type has none."""
    kind = _system_type(study)
    return kind.contact_line if kind is not None else None


def _position_label(study: StudyResult) -> str | None:
    """Axis label of the contact nodes' ``x`` when it is a position (block: along AB; gmsh body:
    along the obstacle's tangent), None when nodes are only numbered (particles, matrices)."""
    kind = _system_type(study)
    return (kind.position_axis.format(length=study.units.length)
            if kind is not None and kind.position_axis else None)


def _few_states(ax, idx: np.ndarray, is_load: bool = False) -> None:
    """A study of one or a few states: integer ticks on the state-index axis."""
    if len(idx) <= 3 and not is_load:
        ax.set_xticks(idx)
        ax.set_xlim(idx.min() - 0.5, idx.max() + 0.5)


def status_map(study: StudyResult, outdir: pathlib.Path) -> list[pathlib.Path]:
    """The contact status (stick, slip, free, zero) of every node at every state: one row per node at
    its position along the contact line, states left to right; ``status_map.png`` and ``.svg`` in
    ``outdir``, whose paths are returned."""
    plt = _plt()
    import matplotlib
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch
    states = study.states
    n = len(states[0].nodes)
    codes = np.array([[STATUS_ORDER.index(nd.status) for nd in s.nodes] for s in states]).T
    xs = np.array([nd.x for nd in states[0].nodes])
    x_load, xlabel, is_load = load_axis(study.states, study.units)
    fig, ax = plt.subplots(figsize=(10, 4.2))
    cmap = ListedColormap([STATUS_COLOURS[k] for k in STATUS_ORDER])
    # node rows at their positions along AB: edges halfway between neighbours; nodes that do not
    # increase strictly along it (e.g. a contact curve folding back over the obstacle) as numbered rows
    label, line = _position_label(study), _contact_line(study)
    if label and n > 1 and np.any(np.diff(xs) <= 0):
        xs, label, line = np.arange(n, dtype=float), None, None
    if n > 1:
        mid = 0.5 * (xs[1:] + xs[:-1])
        yedges = np.concatenate([[xs[0] - (mid[0] - xs[0])], mid, [xs[-1] + (xs[-1] - mid[-1])]])
    else:
        yedges = np.array([xs[0] - 0.5, xs[0] + 0.5])
    xedges = _edges(x_load)
    # what pcolormesh(xedges, yedges, codes) draws, as one rectangle per run of equal status along a
    # node's row: the same picture, but the SVG holds ~100 rectangles instead of n x states quads
    rects, colours = [], []
    for r, row in enumerate(codes):
        cut = np.flatnonzero(np.diff(row)) + 1
        for a, b in zip(np.concatenate([[0], cut]), np.concatenate([cut, [len(row)]])):
            x0, x1, y0, y1 = xedges[a], xedges[b], yedges[r], yedges[r + 1]
            rects.append([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
            colours.append(cmap(BoundaryNorm(np.arange(-0.5, 4.5), 4)(row[a])))
    runs = PolyCollection(rects, facecolors=colours, edgecolors="none", antialiaseds=False,
                          snap=matplotlib.rcParams["pcolormesh.snap"])
    ax.add_collection(runs)
    runs.sticky_edges.x[:] = [xedges.min(), xedges.max()]
    runs.sticky_edges.y[:] = [yedges.min(), yedges.max()]
    length = study.units.length
    ax.set_xlabel(xlabel)
    ax.hlines(yedges[1:-1], xedges[0], xedges[-1], colors="white", linewidth=0.6)    # one row per node
    if n <= 12 or not label:
        ax.set_yticks(xs)
        ax.set_yticklabels([f"{x:g}" for x in xs] if label else [f"node {i}" for i in range(n)])
    ax.set_ylabel(f"contact node position x [{length}] ({line[0]} at the bottom)" if line
                  else label or "contact node")
    _few_states(ax, x_load, is_load)
    _mark_phases(ax, states, x_load)
    present = sorted({s for row in codes for s in row})
    ax.legend(handles=[Patch(color=STATUS_COLOURS[STATUS_ORDER[k]], label=STATUS_ORDER[k]) for k in present],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(_title(study, f"contact status of the {n} contact nodes {_along(study)}"), pad=TITLE_PAD)
    return _save(fig, outdir / "status_map")


def reactions(study: StudyResult, pictured: list[int], outdir: pathlib.Path) -> list[pathlib.Path]:
    """Normal and tangential reactions along the contact at the ``pictured`` states (the final state
    when none of them is a state of the study), with the Coulomb limits ``+-mu |r_N|`` and the slip
    nodes marked; ``reactions.png`` and ``.svg`` in ``outdir``, whose paths are returned."""
    plt = _plt()
    by_index = {s.index: s for s in study.states}
    ids = [i for i in pictured if i in by_index] or [study.final.index]
    mu = _num(study.mu)
    force = study.units.force
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    many = len(ids) > 8
    cmap = plt.get_cmap("viridis")
    # each pictured state's load, where the loading has one (the plots' x-axis, its unit)
    x_load, load_label, is_load = load_axis(study.states, study.units)
    load_of = dict(zip((s.index for s in study.states), x_load)) if is_load else {}
    load_unit = load_label.rsplit("[", 1)[-1].rstrip("]") if is_load and "[" in load_label else ""
    for k, i in enumerate(ids):
        s = by_index[i]
        x = np.array([nd.x for nd in s.nodes])
        rn = -np.array([nd.r_N for nd in s.nodes])
        rt = np.array([nd.r_T for nd in s.nodes])
        c = cmap(k / max(len(ids) - 1, 1)) if many else f"C{k % 10}"
        cl = s.classification
        at = f" at load {load_of[i]:.3g} {load_unit}" if i in load_of else ""
        label = None if many else f"state {i}{at} ({cl.stick} stick / {cl.slip} slip / {cl.free} free)"
        a1.plot(x, rn, "-o", color=c, ms=3.5, lw=1.2, label=label)
        a2.plot(x, rt, "-o", color=c, ms=3.5, lw=1.2)
        if np.isfinite(mu):
            a2.plot(x, mu * rn, ls="--", color=c, lw=0.8, alpha=0.7)
            a2.plot(x, -mu * rn, ls="--", color=c, lw=0.8, alpha=0.7)
        slip = np.array([nd.status == "slip" for nd in s.nodes])
        a2.plot(x[slip], rt[slip], "s", mfc="none", mec=STATUS_COLOURS["slip"], ms=6)
    a1.set_ylabel(f"normal reaction -r_N [{force}]\n(compression > 0)")
    a2.set_ylabel(f"tangential reaction r_T [{force}]\n(dashed: \u00b1\u03bc |r_N|)")
    a2.set_xlabel(_position_label(study) or "contact node")
    if not _position_label(study):
        a2.set_xticks(x)
    for a in (a1, a2):
        a.axhline(0, color="0.5", lw=0.6)
        a.grid(alpha=0.3)
    if many:
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(min(ids), max(ids)))
        fig.colorbar(sm, ax=(a1, a2), label="state index")
    else:
        a1.legend(fontsize=8)
    a2.plot([], [], "s", mfc="none", mec=STATUS_COLOURS["slip"], label="slip nodes (on the Coulomb limit)")
    a2.plot([], [], "--", color="0.4", lw=0.8, label="Coulomb limits \u00b1\u03bc |r_N|")
    a2.legend(fontsize=8, loc="best")
    line = _contact_line(study)
    where = f"along {line}" if line else "along the obstacle" if _position_label(study) else "at the contact nodes"
    a1.set_title(_title(study, f"reactions {where} (\u03bc = {study.mu})"))
    return _save(fig, outdir / "reactions")


def mceip_mu(study: StudyResult, outdir: pathlib.Path) -> list[pathlib.Path]:
    """MCEIP-mu along the loading: every value found and the smallest one at each state, the scene's
    mu and the number of slip nodes; ``mceip_mu.png`` and ``.svg`` in ``outdir``, whose paths are
    returned."""
    plt = _plt()
    from matplotlib.ticker import MaxNLocator
    states = study.states
    idx, xlabel, is_load = load_axis(study.states, study.units)
    nslip = np.array([s.classification.slip for s in states])
    best = np.full(len(states), np.nan)
    fig, ax = plt.subplots(figsize=(10, 4.5))
    allx, ally = [], []
    for k, s in enumerate(states):
        vals = [float(v) for v in s.mu_values()]
        if vals:
            best[k] = min(vals)
            allx += [idx[k]] * len(vals)
            ally += vals
    positive = np.concatenate([best[np.isfinite(best) & (best > 0)], [v for v in ally if v > 0]])
    ax.plot(allx, ally, ".", color="0.6", ms=3, label="every MCEIP-\u03bc value found")
    ax.plot(idx, best, "-", color="C0", lw=1.6, drawstyle="steps-mid", marker="o" if len(idx) <= 3 else None,
            label="smallest MCEIP-\u03bc value")
    lone = _isolated(best)
    if lone.any() and len(idx) > 3:
        ax.plot(idx[lone], best[lone], "o", color="C0", ms=4)
    if len(idx) > 3 and np.isfinite(best[-1]):       # the final state's value, marked and written
        ax.plot(idx[-1], best[-1], "o", color="C0", ms=5)
        ax.annotate(f"final {best[-1]:.4g}", (idx[-1], best[-1]), xytext=(-6, 6), textcoords="offset points",
                    ha="right", va="bottom", fontsize=8, color="C0")
    mu = _num(study.mu)
    if np.isfinite(mu):
        ax.axhline(mu, color="C3", ls="--", lw=1.2, label=f"scene \u03bc = {mu:g}")
    if len(positive) and positive.max() / max(positive.min(), 1e-300) > 50:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("critical friction coefficient \u03bc (MCEIP-\u03bc)")
    _mark_phases(ax, states, idx)
    ax2 = ax.twinx()
    ax2.step(idx, nslip, where="mid", color="C2", lw=1.0, alpha=0.8, marker="s" if len(idx) <= 3 else None,
             label="slip nodes")
    _few_states(ax, idx, is_load)
    ax2.set_ylabel("number of slip nodes", color="C2")
    ax2.tick_params(axis="y", colors="C2")
    ax2.set_ylim(0, max(1, nslip.max()) * 1.05)
    ax2.yaxis.set_major_locator(MaxNLocator(integer=True))     # a number of nodes
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=4, frameon=False)
    if not np.isfinite(best).any():
        ax.text(0.5, 0.5, "no MCEIP-\u03bc solution at any state", transform=ax.transAxes, ha="center", color="0.3")
    ax.grid(alpha=0.3)
    ax.set_title(_title(study, f"MCEIP-\u03bc (transition to divergence) {_along(study)}"), pad=TITLE_PAD)
    return _save(fig, outdir / "mceip_mu")


def necessary(study: StudyResult, outdir: pathlib.Path) -> list[pathlib.Path]:
    """The necessary condition (19) along the loading: the smallest eigenvalue of sym K*(mu) at each
    state, the states where (19) holds shaded, a note when sym M*(mu) is indefinite somewhere;
    ``necessary.png`` and ``.svg`` in ``outdir``, whose paths are returned."""
    plt = _plt()
    states = study.states
    idx, xlabel, is_load = load_axis(study.states, study.units)
    # the record as the state holds it (an analysis that failed has no eigenvalue: NaN)
    recs = [s.analyses.necessary for s in states]
    lamK = np.array([_num(None if r is None else r.min_eig_K_sym) for r in recs])
    lamM = np.array([_num(None if r is None else r.min_eig_M_sym) for r in recs])
    fig, ax = plt.subplots(figsize=(10, 4.2))
    ax.plot(idx, lamK, "-", color="C0", lw=1.5, drawstyle="steps-mid", marker="o" if len(idx) <= 3 else None,
            label="smallest eigenvalue of sym K*(\u03bc)")
    lone = _isolated(lamK)
    if lone.any() and len(idx) > 3:
        ax.plot(idx[lone], lamK[lone], "o", color="C0", ms=4)
    # where the budget of exact values was spent, the bounds the value lies in
    within = [None if r is None else getattr(r, "min_eig_K_sym_bounds", None) for r in recs]
    lo = np.array([np.nan if b is None else b[0] for b in within])
    hi = np.array([np.nan if b is None else b[1] for b in within])
    if np.isfinite(lo).any():
        ax.fill_between(idx, lo, hi, where=np.isfinite(lo), color="C0", alpha=0.3, step="mid", lw=0,
                        label="smallest eigenvalue of sym K*(\u03bc) lies here (bounds)")
    _few_states(ax, idx, is_load)
    ax.axhline(0, color="0.3", lw=0.8)
    sat = np.array([r is not None and bool(r.satisfied) for r in recs])
    if sat.any():
        ax.fill_between(idx, 0, 1, where=sat, transform=ax.get_xaxis_transform(), color="C3", alpha=0.08,
                        step="mid", label="necessary condition (19) holds")
    finite = lamK[np.isfinite(lamK)]
    if len(finite) and np.abs(finite).max() > 100 * max(np.abs(finite[finite != 0]).min(initial=1.0), 1e-300):
        ax.set_yscale("symlog", linthresh=max(np.abs(finite[finite != 0]).min(initial=1.0), 1e-12))
    if np.isfinite(lamM).any() and np.nanmin(lamM) < 0:
        ax.text(0.99, 0.02, f"sym M*(\u03bc) is indefinite at some states (min {np.nanmin(lamM):.3g})",
                transform=ax.transAxes, ha="right", fontsize=8, color="C3")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"min eig sym K*(\u03bc) [{study.units.stiffness or 'N/mm'}]")
    _mark_phases(ax, states, idx)
    if np.isfinite(lo).any():     # the bounds fill the axes where the value falls: the legend below them
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=3, frameon=False)
    else:
        ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    ax.set_title(_title(study, f"necessary condition (19) at \u03bc = {study.mu}"), pad=TITLE_PAD)
    return _save(fig, outdir / "necessary")


def transient(study: StudyResult, record, outdir: pathlib.Path) -> list[pathlib.Path]:
    """The dynamics from one state (results.json ``transient``): the mode's amplitude over its start,
    ``|a(t)| / eps``, on a log axis for each step of the dt study, with ``exp(lambda t)`` of the
    prediction dashed; ``transient_s<state>.png`` and ``.svg`` in ``outdir``."""
    plt = _plt()
    time_unit = study.units.time or "s"
    fig, ax = plt.subplots(figsize=(9, 4.6))
    for k, run in enumerate(record.runs):
        t = np.asarray(run.series["t"], dtype=float)
        a = np.abs(np.asarray(run.series["amplitude"], dtype=float)) / float(record.eps)
        rate = "" if run.measured_rate is None else f", fitted {run.measured_rate:.5g} 1/{time_unit}"
        ax.semilogy(t, np.maximum(a, 1e-300), "-", color=f"C{k}", lw=1.4,
                    label=f"dt = {run.dt:.3g} {time_unit}{rate}")
    if record.predicted_rate is not None and record.runs:
        t = np.asarray(record.runs[-1].series["t"], dtype=float)
        ax.semilogy(t, np.exp(float(record.predicted_rate) * t), "k--", lw=1.0,
                    label=f"exp(\u03bb t), \u03bb = {float(record.predicted_rate):.5g} 1/{time_unit} (MCEIP-\u03bb\u00b2)")
    ax.set_xlabel(f"time t [{time_unit}]")
    ax.set_ylabel("mode amplitude |a(t)| / its start")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    what = ("the divergence mode" if record.predicted_rate is not None
            else "a push of the slip nodes (no divergence mode at this \u03bc)")
    ax.set_title(_title(study, f"dynamics from state {record.state} at \u03bc = {float(record.mu):g}: {what}"))
    return _save(fig, outdir / f"transient_s{record.state:04d}")


def draw_plots(study: StudyResult, pictured: list[int],
               outdir: pathlib.Path) -> tuple[list[pathlib.Path], list[str]]:
    """Every plot the study allows and the scene asked for; returns (files, notes for the report)."""
    files, notes = [], []
    files += status_map(study, outdir)
    files += reactions(study, pictured, outdir)
    asked = study.analyses_requested
    if "mceip_mu" in asked:                # the analyses' plots only when the scene asked for them
        files += mceip_mu(study, outdir)   # (no warning otherwise: that was the user's choice)
    if "necessary" in asked:
        files += necessary(study, outdir)
    for record in study.transient or ():
        if record.runs:
            files += transient(study, record, outdir)
    return files, notes


def draw_job(job: dict) -> tuple[list[pathlib.Path], list[str]]:
    """Draw the plots of a drawing process's job (app/plot/worker.py): the study
    (``results``: its results.json document), the ``pictured`` states and the folder ``plots_dir``."""
    return draw_plots(StudyResult.from_json(job["results"]), job["pictured"], pathlib.Path(job["plots_dir"]))


def warm_up(_arg: str = "") -> None:
    """Import matplotlib and draw a small figure to PNG and SVG in memory (fonts loaded and
    cached), before the plots are asked for (app/plot/worker.py)."""
    import io
    plt = _plt()
    from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: F401 - imported for status_map
    from matplotlib.patches import Patch  # noqa: F401
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1], "-o", label="warm-up \u03bc")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.set_title("warm-up")
    for ext in ("png", "svg"):
        fig.savefig(io.BytesIO(), format=ext, dpi=150 if ext == "png" else None, bbox_inches="tight")
    plt.close(fig)
