"""The combined table of a sweep: one row of quantities of interest per case (``sweep.csv``,
``sweep.json``), the plots of each quantity against a swept key, and the printed summary.
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import pathlib
import re
import tempfile
from typing import Any

from app.io.result import StateResult, StudyResult
from app.io.results import file_mode
from app.io.select import load_axis
from app.scene.schema import Scene
from app.scene.sweep import Case, format_value

QUANTITIES = [   # (column, description), in table order after the swept keys
    ("status", "ok | incomplete (some states failed) | error: ..."),
    ("path_end", "how the loading path ended"),
    ("n_states", "equilibrium states on the path"),
    ("distinct_classifications", "distinct (classification, signs) along the path"),
    ("n_contact_nodes", "contact candidate nodes"),
    ("L_over_H", "aspect ratio of the block"),
    ("final_u_x", "CD displacement u_x at the final state [length]"),
    ("final_n_slip", "slip nodes at the final state"),
    ("final_n_stick", "stick nodes at the final state"),
    ("final_n_free", "free nodes at the final state"),
    ("final_n_zero", "zero-reaction nodes at the final state"),
    ("final_mceip_mu_min", "smallest MCEIP-mu at the final state"),
    ("final_mceip_mu_count", "MCEIP-mu solutions found at the final state"),
    ("first_mceip_mu_state", "index of the first state with an MCEIP-mu solution"),
    ("first_mceip_mu_u_x", "CD u_x at that state [length]"),
    ("first_mceip_mu_value", "smallest MCEIP-mu at that state"),
    ("first_mceip_mu_n_slip", "slip nodes at that state"),
    ("first_mceip_mu_n_stick", "stick nodes at that state"),
    ("first_mceip_mu_n_free", "free nodes at that state"),
    ("first_mceip_mu_slip_fraction", "slip nodes / nodes in contact at that state"),
    ("first_mceip_mu_u_x_fraction", "CD u_x at that state / CD u_x at the final state"),
    ("states_with_mceip_mu", "states with at least one MCEIP-mu solution"),
    ("states_without_mceip_mu_after_first", "states after the first solution where none was found"),
    ("mceip_mu_decreases_as_slip_spreads", "between consecutive states with solutions, the smallest MCEIP-mu "
                                           "drops whenever the number of stick nodes drops"),
    ("mceip_mu_max_rise", "largest relative rise of the smallest MCEIP-mu from one state with solutions to the "
                          "next (0: it never rises along the path)"),
    ("final_load", "the load at the final state, as the plots' x-axis measures it: the distance CD "
                   "travelled (the block), the distance a loading program's parameters travelled (one unit); "
                   "the unit in load_label"),
    ("first_mceip_mu_load", "the load at the first state with an MCEIP-mu solution (as final_load)"),
    ("load_label", "what final_load and first_mceip_mu_load measure, with the unit"),
    ("wall_seconds", "wall time of the case's study [s]"),
    ("ranks", "MPI ranks that ran the case"),
    ("ran", "'this run' or 'earlier' (skipped on restart: results.json already complete)"),
]

#: the quantity (a key of the units block) of the columns with a unit: ``[length]`` above; sweep.csv
#: headers name the scene's unit (``final_u_x [mm]``), sweep.json has a ``units`` block
UNIT_OF = {"final_u_x": "length", "first_mceip_mu_u_x": "length"}


#: the plotted columns in panel order: (column, title in words, y-axis label; ``{load}`` is the case's
#: load label, ``{length}`` the length unit). The wall time is a cost, not a result: it is in the
#: tables, not in the plots.
PLOTTED = [
    ("final_mceip_mu_min", "critical \u03bc at the final state", "smallest MCEIP-\u03bc"),
    ("first_mceip_mu_value", "critical \u03bc where MCEIP-\u03bc first has a solution", "smallest MCEIP-\u03bc"),
    ("first_mceip_mu_load", "load where MCEIP-\u03bc first has a solution", "{load}"),
    ("first_mceip_mu_n_slip", "slip nodes where MCEIP-\u03bc first has a solution", "slip nodes"),
    ("first_mceip_mu_slip_fraction", "share of the contact slipping there", "slip / in contact"),
    ("final_load", "load at the final state", "{load}"),
    ("final_n_slip", "slip nodes at the final state", "slip nodes"),
    ("final_n_stick", "stick nodes at the final state", "stick nodes"),
    ("n_states", "equilibrium states on the path", "states"),
]


def _min_mu(state: StateResult) -> float | None:
    """The state's smallest MCEIP-mu as a plain float (None when MCEIP-mu found none or gave no answer)."""
    m = state.min_mu()
    return None if m is None else float(m)


def case_row(study: StudyResult, case: Case, ran: str = "this run") -> dict:
    """One row of the combined table from a case's study (run now, or read from its results.json)."""
    row: dict[str, Any] = {"case": case.name, "index": case.index}
    row.update({k: format_value(v) if isinstance(v, (list, tuple)) else v for k, v in case.values.items()})
    row.update({q: None for q, _ in QUANTITIES})
    states = study.states
    fails = study.failures
    row["status"] = f"incomplete ({len(fails)} state(s) failed)" if fails else "ok"
    row["path_end"] = study.path.end.split(":")[0]
    row["n_states"] = len(states)
    row["distinct_classifications"] = study.distinct_classifications
    row["wall_seconds"] = study.wall_seconds
    row["ranks"] = study.mpi_ranks
    row["ran"] = ran
    columns = getattr(case.scene.system, "table_columns", None)   # e.g. the block's L/H (app/systems/)
    if columns is not None:
        row.update(columns())
    if not states:
        return row
    last = states[-1]
    row["n_contact_nodes"] = len(last.nodes)
    row["final_u_x"] = last.load.u_x
    x_load, load_label, is_load = load_axis(states, study.units)
    if is_load:
        row["load_label"], row["final_load"] = load_label, float(x_load[-1])
    row.update(_parameters("final", last, study))
    for k in ("slip", "stick", "free", "zero"):
        row[f"final_n_{k}"] = getattr(last.classification, k)
    if "mceip_mu" in study.analyses_requested:
        row["final_mceip_mu_min"] = _min_mu(last)
        record = last.analyses.mceip_mu          # as written, answered or not
        row["final_mceip_mu_count"] = 0 if record is None else len(record.solutions)
        mins = [_min_mu(s) for s in states]
        first = next((i for i, m in enumerate(mins) if m is not None), None)
        row["states_with_mceip_mu"] = sum(m is not None for m in mins)
        if first is not None:
            st = states[first]
            c = st.classification
            row["first_mceip_mu_state"] = st.index
            row["first_mceip_mu_u_x"] = st.load.u_x
            if is_load:
                row["first_mceip_mu_load"] = float(x_load[first])
            row.update(_parameters("first_mceip_mu", st, study))
            row["first_mceip_mu_value"] = mins[first]
            row["first_mceip_mu_n_slip"], row["first_mceip_mu_n_stick"] = c.slip, c.stick
            row["first_mceip_mu_n_free"] = c.free
            in_contact = c.slip + c.stick + c.zero
            row["first_mceip_mu_slip_fraction"] = c.slip / in_contact if in_contact else None
            ux0, ux1 = row["first_mceip_mu_u_x"], row["final_u_x"]
            if isinstance(ux0, (int, float)) and isinstance(ux1, (int, float)) and ux1 != 0:
                row["first_mceip_mu_u_x_fraction"] = ux0 / ux1
            row["states_without_mceip_mu_after_first"] = sum(m is None for m in mins[first:])
            found = [(m, s.classification.stick) for m, s in zip(mins[first:], states[first:]) if m is not None]
            pairs = list(zip(found, found[1:]))
            row["mceip_mu_decreases_as_slip_spreads"] = all(b < a for (a, sa), (b, sb) in pairs if sb < sa)
            row["mceip_mu_max_rise"] = max([0.0] + [b / a - 1 for (a, _), (b, _) in pairs if a > 0])
    return row


def _parameters(prefix: str, state: StateResult, study: StudyResult) -> dict:
    """A loading program's load parameters at ``state`` as columns ``<prefix>:<parameter>`` (e.g.
    ``final:motion.top.tx``), none for a loading without named parameters (the block)."""
    return {f"{prefix}:{k}": float(v) for k, v in sorted((state.load.parameters or {}).items())
            if isinstance(v, (int, float))}


def parameter_columns(rows: dict[int, dict]) -> list[str]:
    """The load-parameter columns (:func:`_parameters`) found in any row, final ones first."""
    found = {k for r in rows.values() for k in r if ":" in k and k.split(":")[0] in ("final", "first_mceip_mu")}
    return sorted(found, key=lambda k: (k.split(":")[0] != "final", k))


def error_row(case: Case, message: str, ran: str = "this run") -> dict:
    """The sweep table's row of a case that failed: its name, index and swept values, every quantity
    empty, status ``error: <message>`` and ``ran`` (``this run`` or ``earlier``)."""
    row: dict[str, Any] = {"case": case.name, "index": case.index}
    row.update({k: format_value(v) if isinstance(v, (list, tuple)) else v for k, v in case.values.items()})
    row.update({q: None for q, _ in QUANTITIES})
    row["status"], row["ran"] = f"error: {message}", ran
    return row


def _columns(cases: list[Case], rows: dict[int, dict]) -> list[str]:
    return ["case", "index", *cases[0].values.keys(), *(q for q, _ in QUANTITIES), *parameter_columns(rows)]


def _header(column: str, units: dict) -> str:
    """sweep.csv's header of a column: with its unit, a load parameter's from its name."""
    from app.io.results import csv_header
    from app.io.select import parameter_unit
    if ":" in column:
        unit = parameter_unit(column.split(":", 1)[1], units)
        return f"{column} [{unit}]" if unit else column
    return csv_header(column, UNIT_OF.get(column), units)


def write_tables(outdir: pathlib.Path, scene: Scene, cases: list[Case], rows: dict[int, dict],
                 info: dict) -> None:
    """sweep.csv and sweep.json (atomically): one row per case, finished or not."""
    from app.io.document import NON_FINITE_REASON, json_clean
    from app.io.results import atomic_write
    from app.systems.units import CONTINUUM_UNITS
    cols = _columns(cases, rows)
    table = []
    for c in cases:
        row = rows.get(c.index)
        if row is None:
            row = {**error_row(c, ""), "status": "not run", "ran": None}
        table.append({k: row.get(k) for k in cols})
    units = CONTINUUM_UNITS[scene.units]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([_header(k, units) for k in cols])
    for r in table:
        w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in r.values()])
    atomic_write(outdir / "sweep.csv", buf.getvalue())
    missing = [r["case"] for r in table if r["status"] == "not run"]
    doc = {"scene": scene.name, "sweep": scene.sweep.model_dump(mode="json"), "n_cases": len(cases),
           "complete": not missing, "missing": missing, **info,
           "units": {k: units[k] for k in ("length", "force", "time")},
           "columns": {"case": "stable case name (cases/<case>/ holds its results.json, steps.csv)",
                       "index": "case number in sweep order (from 0)",
                       **{k: "swept key" for k in cases[0].values}, **dict(QUANTITIES),
                       **{k: f"load parameter {k.split(':', 1)[1]} at the "
                             f"{'final state' if k.startswith('final:') else 'first state with an MCEIP-mu solution'}"
                          for k in parameter_columns(rows)}},
           "cases": table}
    non_finite: dict[str, str] = {}
    data = json_clean(doc, non_finite)
    if non_finite:
        data["non_finite"] = {"reason": NON_FINITE_REASON, "values": non_finite}
    atomic_write(outdir / "sweep.json", json.dumps(data, indent=1, allow_nan=False))


#: swept scene keys in words and the quantity of their unit (a key of the units block; None: no unit)
KEY_LABELS = {
    "mu": ("friction coefficient \u03bc", None),
    "system.length": ("block length L", "length"), "system.height": ("block height H", "length"),
    "system.thickness": ("thickness", "length"), "system.E": ("Young's modulus E", "stress"),
    "system.nu": ("Poisson's ratio \u03bd", None), "system.density": ("density", "density"),
    "system.nx": ("cells along the contact side (nx)", None), "system.ny": ("cells across (ny)", None),
    "system.material.E": ("Young's modulus E", "stress"), "system.material.nu": ("Poisson's ratio \u03bd", None),
    "system.material.density": ("density", "density"),
    "loading.normal_force": ("normal force", "force"), "loading.normal_steps": ("normal load steps", None),
    "loading.tangential_step": ("tangential step", "length"),
    "loading.tangential_max": ("largest tangential motion", "length"),
}


def key_label(key: str, units: dict) -> str:
    """A swept key as an axis label: in words with its unit where known (``block length L [mm]``),
    the key itself otherwise."""
    words, quantity = KEY_LABELS.get(key, (key, None))
    unit = units.get(quantity) if quantity else None
    return f"{words} [{unit}]" if unit else words


def _ending(r: dict) -> str:
    """How a case's path ended, for the plots' markers ("gross sliding", "all phases applied", ...,
    without where), or its status when it did not run to the end."""
    if r.get("status") != "ok":
        return str(r.get("status") or "not run").split(":")[0].split(" (")[0]
    end = str(r.get("path_end"))
    return "gross sliding" if "gross sliding" in end else end


def _numeric(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def write_plots(outdir: pathlib.Path, mode: str, cases: list[Case], rows: dict[int, dict],
                units: dict | None = None) -> list[pathlib.Path]:
    """One PNG per swept key: every plotted quantity (:data:`PLOTTED`, titled in words with units)
    against it, one line per value of the other swept keys in a product sweep; log axes where a
    quantity spans more than a decade; cases whose path ended otherwise than most (or that failed)
    drawn with open markers and named under the panels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    units = units or {}
    keys = list(cases[0].values)
    out = []
    (outdir / "plots").mkdir(exist_ok=True)
    table = [(c, rows.get(c.index) or {}) for c in cases]
    endings = [_ending(r) for _, r in table if r]
    usual = max(set(endings), key=endings.count) if endings else None
    loads = {r.get("load_label") for _, r in table if r.get("load_label")}
    described = loads.pop() if len(loads) == 1 else None
    # a load axis is labelled "load [unit]"; what the load measures is said under the panels
    load = f"load [{described.rsplit('[', 1)[1]}" if described and "[" in described else "load (see load_label)"
    for key in keys:
        panels = [(q, title, ylabel.format(load=load)) for q, title, ylabel in PLOTTED
                  if any(_numeric(r.get(q)) for _, r in table)]
        if not panels:
            continue
        xs_all = [c.values[key] for c, _ in table]
        numeric = all(_numeric(x) for x in xs_all)
        categories = list(dict.fromkeys(format_value(x) for x in xs_all))
        others = [k for k in keys if k != key]
        series: dict[str, list] = {}
        for c, r in table:
            label = ", ".join(f"{k}={format_value(c.values[k])}" for k in others) if mode != "zip" else ""
            series.setdefault(label, []).append((c, r))
        ncol = min(3, len(panels))
        nrow = math.ceil(len(panels) / ncol)
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.4 * ncol, 3.3 * nrow), squeeze=False)
        odd: dict[str, list[str]] = {}
        for ax, (q, title, ylabel) in zip(axes.flat, panels):
            _panel(ax, q, series, key, numeric, categories, usual, odd)
            ax.set_title(title, fontsize=9)
            ax.set_ylabel(ylabel, fontsize=8)
            ax.set_xlabel(key_label(key, units), fontsize=8)
        for ax in list(axes.flat)[len(panels):]:
            ax.set_visible(False)
        if len(series) > 1:
            axes.flat[0].legend(fontsize=6)
        notes = ([f"load: {described.rsplit(' [', 1)[0]}"] if described and any(
            p[2].startswith("load") for p in panels) else [])
        notes += [f"open markers: the path ended with \u201c{end}\u201d ({', '.join(sorted(set(names)))}); "
                 f"the others: \u201c{usual}\u201d" for end, names in odd.items()]
        fig.suptitle(f"{cases[0].scene.name}: results against {key_label(key, units)}", fontsize=10)
        fig.tight_layout(rect=(0, 0.03 * len(notes), 1, 1))
        for k, note in enumerate(notes):
            fig.text(0.01, 0.005 + 0.03 * k, note, fontsize=7, color="0.3")
        path = outdir / "plots" / f"{re.sub(r'[^A-Za-z0-9_.=-]', '-', key)}.png"
        _save_png(fig, path)
        plt.close(fig)
        out.append(path)
    return out


def write_comparison(outdir: pathlib.Path, scene_name: str, studies: list[tuple[str, StudyResult | None]],
                     units: dict | None = None) -> list[pathlib.Path]:
    """``plots/mceip_mu_along_the_loading.png``: each case's smallest MCEIP-\u03bc against its load
    (the plots' load axis, app/io/select.py), one curve per case, to compare where and how low the
    critical friction coefficient falls across the sweep; none when no case has an MCEIP-\u03bc
    value. ``studies``: (case name, its results, None when it has none)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    curves, labels = [], set()
    for name, study in studies:
        if study is None or not study.states or "mceip_mu" not in study.analyses_requested:
            continue
        x, label, _ = load_axis(study.states, study.units)
        y = [_min_mu(s) for s in study.states]
        y = [math.nan if v is None else v for v in y]
        if any(math.isfinite(v) for v in y):
            curves.append((name, x, y))
            labels.add(label)
    if not curves:
        return []
    fig, ax = plt.subplots(figsize=(10, 5))
    cmap = plt.get_cmap("viridis" if len(curves) > 10 else "tab10")
    for k, (name, x, y) in enumerate(curves):
        colour = cmap(k / max(len(curves) - 1, 1)) if len(curves) > 10 else cmap(k % 10)
        ax.plot(x, y, "-", drawstyle="steps-mid", color=colour, lw=1.4, label=name)
        lone = [i for i, v in enumerate(y) if math.isfinite(v)
                and not (i > 0 and math.isfinite(y[i - 1])) and not (i + 1 < len(y) and math.isfinite(y[i + 1]))]
        ax.plot([x[i] for i in lone], [y[i] for i in lone], "o", color=colour, ms=4)
    values = [v for _, _, y in curves for v in y if math.isfinite(v) and v > 0]
    if values and max(values) / min(values) > 10:
        ax.set_yscale("log")
    ax.set_xlabel(labels.pop() if len(labels) == 1 else "load (each case's own axis: see its plots)")
    ax.set_ylabel("critical friction coefficient \u03bc (smallest MCEIP-\u03bc)")
    ax.grid(alpha=0.3)
    if len(curves) <= 12:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, title="case")
    ax.set_title(f"{scene_name}: the critical \u03bc along the loading, one curve per case")
    path = outdir / "plots" / "mceip_mu_along_the_loading.png"
    path.parent.mkdir(exist_ok=True)
    fig.tight_layout()
    _save_png(fig, path)
    plt.close(fig)
    return [path]


def _panel(ax, q: str, series: dict[str, list], key: str, numeric: bool, categories: list[str],
           usual: str | None, odd: dict[str, list[str]]) -> None:
    """One quantity ``q`` against the swept ``key``: a line per series, open markers for the cases
    whose path ended otherwise than ``usual`` (named into ``odd``), a log axis over a decade."""
    from matplotlib.ticker import FuncFormatter, LogLocator
    for k, (label, items) in enumerate(series.items()):
        pts = sorted(((c.values[key] if numeric else categories.index(format_value(c.values[key]))),
                      r.get(q), _ending(r), c.name) for c, r in items if _numeric(r.get(q)))
        if not pts:
            continue
        colour = f"C{k % 10}"
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=colour, lw=1.2, label=label or None)
        for x, y, end, name in pts:
            ax.plot([x], [y], "o", ms=5, color=colour, mfc=colour if end == usual else "white")
            if end != usual:
                odd.setdefault(end, []).append(name)
    ys = [r.get(q) for items in series.values() for _, r in items if _numeric(r.get(q))]
    if ys and min(ys) > 0 and max(ys) / min(ys) > 10:
        ax.set_yscale("log")
        if max(ys) / min(ys) < 100:      # less than two decades: plain labels at 1, 2, 5 x 10^k
            ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
            for axis_formatter in (ax.yaxis.set_major_formatter, ax.yaxis.set_minor_formatter):
                axis_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.tick_params(which="both", labelsize=7)
    if q.endswith(("_n_slip", "_n_stick", "n_states")) and ax.get_yscale() == "linear":
        ax.yaxis.get_major_locator().set_params(integer=True)      # a count: whole numbers
    if not numeric:
        ax.set_xticks(range(len(categories)), categories, rotation=30, ha="right")
    ax.grid(alpha=0.3)


def _save_png(fig, path: pathlib.Path) -> None:
    """The figure as PNG, drawn into a new file and renamed over the old one: a link in its place is
    replaced, never followed."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".png")
    try:
        with os.fdopen(fd, "wb") as f:
            fig.savefig(f, dpi=110, format="png")
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        pathlib.Path(tmp).unlink(missing_ok=True)
        raise


def summary_table(cases: list[Case], rows: dict[int, dict]) -> str:
    """A short plain-text table of the main quantities, one line per case."""
    def f(v, fmt="{:.4g}"):
        return "-" if v is None else (fmt.format(v) if isinstance(v, float) else str(v))
    head = ["case", "final \u03bc", "1st \u03bc", "1st state", "1st load", "1st slip", "final slip/stick/free", "s"]
    lines = [head]
    for c in cases:
        r = rows.get(c.index) or {}
        lines.append([c.name, f(r.get("final_mceip_mu_min")), f(r.get("first_mceip_mu_value")),
                      f(r.get("first_mceip_mu_state")), f(r.get("first_mceip_mu_load")),
                      f(r.get("first_mceip_mu_n_slip")),
                      "/".join(f(r.get(f"final_n_{k}")) for k in ("slip", "stick", "free")),
                      f(r.get("wall_seconds"), "{:.1f}")])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    return "\n".join("  " + "  ".join(x.ljust(w) for x, w in zip(row, widths)) for row in lines)
