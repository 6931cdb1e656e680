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
    ("wall_seconds", "wall time of the case's study [s]"),
    ("ranks", "MPI ranks that ran the case"),
    ("ran", "'this run' or 'earlier' (skipped on restart: results.json already complete)"),
]

#: the quantity (a key of the units block) of the columns with a unit: ``[length]`` above; sweep.csv
#: headers name the scene's unit (``final_u_x [mm]``), sweep.json has a ``units`` block
UNIT_OF = {"final_u_x": "length", "first_mceip_mu_u_x": "length"}


PLOTTED = ["final_mceip_mu_min", "first_mceip_mu_value", "first_mceip_mu_u_x", "first_mceip_mu_n_slip",
           "first_mceip_mu_slip_fraction", "first_mceip_mu_u_x_fraction", "final_u_x", "final_n_slip",
           "final_n_stick", "final_n_free", "n_states", "wall_seconds"]


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


def error_row(case: Case, message: str, ran: str = "this run") -> dict:
    """The sweep table's row of a case that failed: its name, index and swept values, every quantity
    empty, status ``error: <message>`` and ``ran`` (``this run`` or ``earlier``)."""
    row: dict[str, Any] = {"case": case.name, "index": case.index}
    row.update({k: format_value(v) if isinstance(v, (list, tuple)) else v for k, v in case.values.items()})
    row.update({q: None for q, _ in QUANTITIES})
    row["status"], row["ran"] = f"error: {message}", ran
    return row


def _columns(cases: list[Case]) -> list[str]:
    return ["case", "index", *cases[0].values.keys(), *(q for q, _ in QUANTITIES)]


def write_tables(outdir: pathlib.Path, scene: Scene, cases: list[Case], rows: dict[int, dict],
                 info: dict) -> None:
    """sweep.csv and sweep.json (atomically): one row per case, finished or not."""
    from app.io.document import NON_FINITE_REASON, json_clean
    from app.io.results import atomic_write, csv_header
    from app.systems.units import CONTINUUM_UNITS
    cols = _columns(cases)
    table = []
    for c in cases:
        row = rows.get(c.index)
        if row is None:
            row = {**error_row(c, ""), "status": "not run", "ran": None}
        table.append({k: row.get(k) for k in cols})
    units = CONTINUUM_UNITS[scene.units]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([csv_header(k, UNIT_OF.get(k), units) for k in cols])
    for r in table:
        w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in r.values()])
    atomic_write(outdir / "sweep.csv", buf.getvalue())
    missing = [r["case"] for r in table if r["status"] == "not run"]
    doc = {"scene": scene.name, "sweep": scene.sweep.model_dump(mode="json"), "n_cases": len(cases),
           "complete": not missing, "missing": missing, **info,
           "units": {k: units[k] for k in ("length", "force", "time")},
           "columns": {"case": "stable case name (cases/<case>/ holds its results.json, steps.csv)",
                       "index": "case number in sweep order (from 0)",
                       **{k: "swept key" for k in cases[0].values}, **dict(QUANTITIES)},
           "cases": table}
    non_finite: dict[str, str] = {}
    data = json_clean(doc, non_finite)
    if non_finite:
        data["non_finite"] = {"reason": NON_FINITE_REASON, "values": non_finite}
    atomic_write(outdir / "sweep.json", json.dumps(data, indent=1, allow_nan=False))


def write_plots(outdir: pathlib.Path, mode: str, cases: list[Case], rows: dict[int, dict]) -> list[pathlib.Path]:
    """One PNG per swept key: every plotted quantity against it (one line per value of the
    other swept keys in a product sweep)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = list(cases[0].values)
    out = []
    (outdir / "plots").mkdir(exist_ok=True)
    table = [(c, rows.get(c.index) or {}) for c in cases]
    for key in keys:
        quantities = [q for q in PLOTTED if any(isinstance(r.get(q), (int, float)) and not isinstance(r.get(q), bool)
                                                 for _, r in table)]
        if not quantities:
            continue
        xs_all = [c.values[key] for c, _ in table]
        numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in xs_all)
        categories = list(dict.fromkeys(format_value(x) for x in xs_all))
        others = [k for k in keys if k != key]
        series: dict[str, list] = {}
        for c, r in table:
            label = ", ".join(f"{k}={format_value(c.values[k])}" for k in others) if mode != "zip" else ""
            series.setdefault(label, []).append((c, r))
        ncol = min(3, len(quantities))
        nrow = math.ceil(len(quantities) / ncol)
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.1 * nrow), squeeze=False)
        for ax, q in zip(axes.flat, quantities):
            for label, items in series.items():
                pts = [((c.values[key] if numeric else categories.index(format_value(c.values[key]))), r.get(q))
                       for c, r in items]
                pts = sorted((x, y) for x, y in pts if isinstance(y, (int, float)) and not isinstance(y, bool))
                if pts:
                    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", ms=4, label=label or None)
            ys = [r.get(q) for _, r in table if isinstance(r.get(q), (int, float))]
            if "mceip_mu" in q and ys and min(ys) > 0 and max(ys) / min(ys) > 50:
                ax.set_yscale("log")
            ax.set_title(q, fontsize=9)
            ax.set_xlabel(key, fontsize=8)
            ax.tick_params(labelsize=7)
            if not numeric:
                ax.set_xticks(range(len(categories)), categories, rotation=30)
            ax.grid(alpha=0.3)
        for ax in list(axes.flat)[len(quantities):]:
            ax.set_visible(False)
        if len(series) > 1:
            axes.flat[0].legend(fontsize=6)
        fig.suptitle(f"{cases[0].scene.name}: quantities against {key}", fontsize=10)
        fig.tight_layout()
        path = outdir / "plots" / f"{re.sub(r'[^A-Za-z0-9_.=-]', '-', key)}.png"
        # drawn into a new file and renamed over the old one: a link in its place is replaced, never followed
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".png")
        try:
            with os.fdopen(fd, "wb") as f:
                fig.savefig(f, dpi=90, format="png")
            os.chmod(tmp, file_mode())
            os.replace(tmp, path)
        except BaseException:
            pathlib.Path(tmp).unlink(missing_ok=True)
            raise
        plt.close(fig)
        out.append(path)
    return out


def summary_table(cases: list[Case], rows: dict[int, dict]) -> str:
    """A short plain-text table of the main quantities, one line per case."""
    def f(v, fmt="{:.4g}"):
        return "-" if v is None else (fmt.format(v) if isinstance(v, float) else str(v))
    head = ["case", "final mu", "1st mu", "1st state", "1st u_x", "1st slip", "final slip/stick/free", "s"]
    lines = [head]
    for c in cases:
        r = rows.get(c.index) or {}
        lines.append([c.name, f(r.get("final_mceip_mu_min")), f(r.get("first_mceip_mu_value")),
                      f(r.get("first_mceip_mu_state")), f(r.get("first_mceip_mu_u_x")),
                      f(r.get("first_mceip_mu_n_slip")),
                      "/".join(f(r.get(f"final_n_{k}")) for k in ("slip", "stick", "free")),
                      f(r.get("wall_seconds"), "{:.1f}")])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    return "\n".join("  " + "  ".join(x.ljust(w) for x, w in zip(row, widths)) for row in lines)
