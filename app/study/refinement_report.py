"""Convergence analysis and report of a mesh-refinement study (app/study/refinement.py): observed
orders, Richardson references, the cheapest level per accuracy, and the files
``refinement.csv``, ``refinement.md``, ``refinement.json``, ``refinement.png``/``.svg`` (error
against h) and ``refinement_cost.png``/``.svg`` (error against time).
"""
from __future__ import annotations

import csv
import io
import json
import math
import pathlib

import numpy as np

from app.io.results import csv_header

QOIS = {  # key: (label, quantity: its unit is the scene's, app/systems/units.py)
    "final_mu": ("final-state smallest MCEIP-mu", "mu"),
    "final_mu_without_point_stick": ("final-state smallest MCEIP-mu without point stick zones", "mu"),
    "first_mu_ux": ("CD u_x at the first MCEIP-mu solution", "length"),
    "lambda2": ("sufficient-condition lambda^2 at mu_fixed (final state)", "lambda2"),
    "depth": ("CD depth for the normal force", "length"),
    "tangential_resultant": ("tangential resultant at the fixed load", "force"),
    "sliding_ux": ("CD u_x at gross sliding", "length"),
    # a loading program (a Gmsh body): the load as the plots' x-axis measures it (app/io/select.py)
    "first_mu_load": ("load at the first MCEIP-mu solution", "load"),
    "sliding_load": ("load at gross sliding", "load"),
}
#: the quantity of the other refinement.csv columns with a unit (``h [mm]``: cell size along AB)
UNIT_OF = {"h": "length", **{k: q for k, (_, q) in QOIS.items()}}
# Stages summed into the columns of the table (the rest is in 'other').
STAGE_GROUPS = {
    "t_mesh_assembly": ("mesh (gmsh)", "assemble stiffness", "assemble mass matrix"),
    "t_factor_W": ("factorise K, contact flexibility",),
    "t_loading": ("quasi-static loading",),
    "t_mceip_mu": ("condensed pencil", "contact Schur complement", "MCEIP-mu (21)-(23)"),
    "t_sufficient": ("reduced pencils", "sufficient condition (17)-(18)"),
}



def observed_order(h: list[float], q: list[float | None]) -> dict:
    """Observed order and reference of one quantity from its values on a refinement sequence.

    Uses the three finest levels with a value. Returns ``p`` (None when it cannot be
    estimated), ``reference``, ``richardson`` (whether the reference is extrapolated), a
    least-squares ``fitted`` slope of log|error| against log h, and a ``note``.
    """
    pts = sorted([(hh, v) for hh, v in zip(h, q) if v is not None and math.isfinite(v)], key=lambda t: t[0])
    out = {"p": None, "reference": None, "richardson": False, "fitted": None, "note": ""}
    if not pts:
        out["note"] = "no value at any level"
        return out
    out["reference"] = pts[0][1]
    if len(pts) < 3:
        out["note"] = "fewer than 3 levels with a value: finest level used as reference"
        return out
    (h1, q1), (h2, q2), (h3, q3) = pts[:3]
    d1, d2 = q2 - q1, q3 - q2
    r = math.sqrt((h2 / h1) * (h3 / h2))
    scale = max(abs(q1), abs(q2), abs(q3), 1e-300)
    if abs(d1) <= 1e-12 * scale:
        out.update(note="the two finest levels agree to 1e-12: finest level used as reference")
    elif abs(d2) <= 1e-12 * scale:
        out.update(note="the two coarser of the three finest levels agree: no order estimate")
    else:
        p = math.log(abs(d2) / abs(d1)) / math.log(r)
        out["p"] = p
        if d1 * d2 < 0:
            out["note"] = "oscillating (differences change sign): no extrapolation, finest level used as reference"
        elif p <= 0.05:
            out["note"] = "differences do not decrease: no convergence observed, finest level used as reference"
        else:
            out["reference"] = q1 + (q1 - q2) / (r ** p - 1.0)
            out["richardson"] = True
            out["note"] = ("monotone: Richardson-extrapolated reference" if p >= 0.5 else
                           "monotone but very slow (p < 0.5): the extrapolated reference is unreliable")
    ref = out["reference"]
    hs, es = [], []
    for hh, v in pts:
        e = abs(v - ref)
        if e > 1e-12 * max(abs(ref), 1e-300):
            hs.append(math.log(hh))
            es.append(math.log(e))
    if len(hs) >= 2:
        out["fitted"] = float(np.polyfit(hs, es, 1)[0])
    return out


def _series(rows: list[dict]) -> dict:
    """The rows per (degree, plane), coarse to fine."""
    out: dict = {}
    for r in rows:
        out.setdefault((r["degree"], r["plane"]), []).append(r)
    return {k: sorted(v, key=lambda r: -r["h"]) for k, v in out.items()}


def series_name(deg: int, rows: list[dict]) -> str:
    """The element of a series in words: ``P1``, ``P2`` or ``P2-P1 mixed`` (every level of a study
    has the scene's element, ``element`` in its row)."""
    from app.systems.schema import element_name
    return element_name(next((r.get("element") for r in rows if r.get("element")), "displacement"), deg)


def level_label(r: dict, short: bool = False) -> str:
    """A level of a row: the block's ``nx=20`` (``20``), a Gmsh body's ``size factor 0.5`` (``x0.5``)."""
    if r.get("nx") is not None:
        return str(r["nx"]) if short else f"nx={r['nx']}"
    return f"x{r['size_factor']:g}" if short else f"size factor {r['size_factor']:g}"


def present(rows: list[dict]) -> list[str]:
    """The quantities of :data:`QOIS` that some level has a value of (the block's or a program's)."""
    return [k for k in QOIS if any(r.get(k) is not None for r in rows)]


def analyse_convergence(rows: list[dict]) -> dict:
    """Orders and references per series (degree, plane), one common reference per plane model and
    quantity, and the relative errors against it (adds ``err_<q>`` to the rows).

    The common reference is the Richardson value of the highest degree whose extrapolation is
    trusted (monotone, p >= 0.5), else the finest level of the highest degree (whose own error is
    then unknown and left out of the plot and of the cheapest-level table).
    """
    conv: dict = {"series": {}, "reference": {}}
    series = _series(rows)
    for (deg, plane), rs in series.items():
        conv["series"][f"{series_name(deg, rows)} {plane}"] = {
            key: observed_order([r["h"] for r in rs], [r.get(key) for r in rs]) for key in QOIS}
    for plane in dict.fromkeys(p for _, p in series):
        degs = sorted((d for d, p in series if p == plane), reverse=True)
        conv["reference"][plane] = {}
        for key in QOIS:
            ref = None
            for d in degs:
                e = conv["series"][f"{series_name(d, rows)} {plane}"][key]
                if e["richardson"] and e["p"] is not None and e["p"] >= 0.5:
                    ref = {"value": e["reference"], "from": f"{series_name(d, rows)} Richardson (p = {e['p']:.2f})"}
                    break
            if ref is None:
                for d in degs:
                    vals = [r for r in series[(d, plane)] if r.get(key) is not None]
                    if vals:
                        fin = min(vals, key=lambda r: r["h"])
                        ref = {"value": fin[key], "from": f"finest {series_name(d, rows)} level ({level_label(fin)}; no trusted "
                                                            f"extrapolation)"}
                        break
            conv["reference"][plane][key] = ref or {"value": None, "from": "no value"}
    for r in rows:
        for key in QOIS:
            ref = conv["reference"][r["plane"]][key]["value"]
            v = r.get(key)
            r[f"err_{key}"] = (abs(v - ref) / max(abs(ref), 1e-300) if v is not None and ref is not None else None)
    return conv


def cheapest(rows: list[dict], key: str, plane: str, targets=(0.1, 0.01, 0.001)) -> dict:
    """For each relative-error target, the cheapest level of the plane model that reaches it
    (against the plane's common reference; a level equal to the reference does not count)."""
    out = {}
    for t in targets:
        ok = [r for r in rows if r["plane"] == plane and r.get(f"err_{key}") is not None
              and 0 < r[f"err_{key}"] <= t]
        out[t] = min(ok, key=lambda r: r["wall_s"]) if ok else None
    return out


# -- outputs -------------------------------------------------------------------------------------
def csv_columns(rows: list[dict]) -> list[str]:
    """refinement.csv's columns: the level, its sizes, the quantities some level has, their errors, times."""
    keys = present(rows)
    level = ["pattern", "nx", "ny"] if any(r.get("nx") is not None for r in rows) else ["size_factor"]
    return ["degree", "element", "plane", *level, "h", "contact_nodes", "dofs", "states", "distinct",
            *keys, "first_mu", "first_mu_label", "final_label", "final_point_stick", "final_mu_proven",
            "final_mu_without_point_stick_proven",
            *[f"err_{k}" for k in keys], "wall_s", *STAGE_GROUPS, "t_other", "first_method", "path_end"]


def fmt(v, digits: int = 6) -> str:
    """A number for the tables (``digits`` significant digits), "-" for none."""
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def markdown(summary: dict) -> str:
    """The text of refinement.md: per degree and plane model the table of levels (sizes, quantities
    of interest, wall times) and the observed orders; per plane model the reference values and the
    cheapest level reaching 10 %, 1 % and 0.1 %; why orders can be poor here; the levels skipped."""
    rows, conv = summary["rows"], summary["convergence"]
    units = summary["units"]
    lines = [f"# Refinement study: {summary['scene']}", "",
             f"{summary['system']}; mu = {summary['mu']}, sufficient condition at mu_fixed = {summary['mu_fixed']}; "
             f"{summary['mpi_ranks']} MPI rank(s); total {summary['wall_seconds']:.1f} s.", ""]
    keys = present(rows)
    for (deg, plane), rs in _series(rows).items():
        heads = [f"{QOIS[k][0]} [{units.get(QOIS[k][1], '?')}]" for k in keys]
        lines += [f"## {series_name(deg, rows)}, plane {plane}", "",
                  "| mesh | contact nodes | DOFs | " + " | ".join(heads) + " | mu at the first solution | wall [s] | "
                  "MCEIP-mu [s] | factor K + W [s] | loading [s] |",
                  "|" + "---|" * (len(keys) + 8)]
        for r in rs:
            mesh = f"{r['nx']} x {r['ny']}" if r.get("nx") is not None else level_label(r)
            lines.append(f"| {mesh} | {r['contact_nodes']} | {r['dofs']} | "
                         + " | ".join(fmt(r.get(k), 6) + (" (not proven)" if r.get(f"{k}_proven") is False
                                                          and r.get(k) is not None else "") for k in keys)
                         + f" | {fmt(r.get('first_mu'), 5)} | {r['wall_s']:.2f} | {r['t_mceip_mu']:.2f} | "
                         f"{r['t_factor_W']:.2f} | {r['t_loading']:.2f} |")
        lines += ["", "| quantity | observed order p (3 finest) | fitted slope | reference | note |",
                  "|---|---|---|---|---|"]
        for key in keys:
            label, quantity = QOIS[key]
            unit = units.get(quantity, "?")
            e = conv["series"][f"{series_name(deg, rows)} {plane}"][key]
            lines.append(f"| {label} [{unit}] | {fmt(e['p'], 3)} | {fmt(e['fitted'], 3)} | "
                         f"{fmt(e['reference'], 7)}{' (Richardson)' if e['richardson'] else ''} | {e['note']} |")
        lines.append("")
    for plane, refs in conv["reference"].items():
        lines += [f"## Plane {plane}: reference values and the cheapest level reaching an accuracy", "",
                  "Relative errors are measured against one reference per quantity (below); the cheapest level "
                  "is the one with the smallest wall time whose error is at most the target.", "",
                  "| quantity | reference | from | 10 % | 1 % | 0.1 % |", "|---|---|---|---|---|---|"]
        for key in keys:
            label, quantity = QOIS[key]
            unit = units.get(quantity, "?")
            ch = cheapest(rows, key, plane)
            cells = [f"{series_name(r['degree'], rows)} {level_label(r)} ({r['wall_s']:.1f} s)" if r else "not reached"
                     for r in ch.values()]
            lines.append(f"| {label} [{unit}] | {fmt(refs[key]['value'], 7)} | {refs[key]['from']} | "
                         + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Why orders can be poor here", "",
              "- The contact zone ends at corners (the block's A and B) and at moving lift-off points, where "
              "the contact pressure is singular: reactions, compliance and eigenvalues converge below the "
              "smooth-problem orders (p ~ 1-1.5 instead of 2).",
              "- The final state is the state at gross sliding (or at the end of the loading), which itself moves with "
              "the mesh (later gross sliding, more nodes lifted off): its critical mu mixes discretisation "
              "error with a change of state, so it may oscillate at the 1e-3 level.",
              "- The first state with an MCEIP-mu solution is a discrete event of the path (which node slips "
              "next, resolved to one load step): path dependence, not a convergent quantity.",
              "- Plane strain with nu near 0.5: P1 triangles lock (too stiff) and P2 converges slowly; values "
              "from these meshes may be far from the limit.", ""]
    points = [r for r in rows if r.get("final_point_stick")]
    if points:
        lines[-1:-1] = [
            f"- A stick zone one node wide: at {len(points)} of {len(rows)} levels the final state has a stick zone "
            "that the mesh does not resolve (`final_point_stick` nodes). While the mesh is far coarser than the "
            "zone, the stiffness it adds falls like 1 / ln(L / h) and so does the final critical mu: its observed "
            "order and extrapolation say nothing. Grade the mesh towards the zone until it spans several nodes, and "
            "make it fine where the zone ends too: the critical mu depends on the end, known to one node spacing "
            "(the paper's block: app/scenes/gmsh/block_adapted.geo). The value with those nodes slipping (\"without point "
            "stick zones\") shows how much the zone weighs; it is not the limit."]
    if summary.get("skipped"):
        lines += ["Skipped: " + "; ".join(summary["skipped"])]
    return "\n".join(lines) + "\n"


#: the quantities in the plots' words (μ and λ² as everywhere in the pictures)
PLOT_TITLES = {
    "final_mu": "final-state smallest MCEIP-\u03bc",
    "final_mu_without_point_stick": "final-state MCEIP-\u03bc, point stick zones slipping",
    "first_mu_ux": "CD u_x at the first MCEIP-\u03bc solution",
    "lambda2": "sufficient-condition \u03bb\u00b2 at \u03bc_fixed (final state)",
    "first_mu_load": "load at the first MCEIP-\u03bc solution",
}


def plot(summary: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    """Two figures of the relative error of each quantity of interest, one series per degree and
    plane model, points labelled with nx: against the cell size h (log-log, each series' fitted
    slope, the observed order, in its legend: ``refinement.png`` and ``.svg``) and against the wall
    time of its level (``refinement_cost.png`` and ``.svg``, what accuracy costs). Returns the paths."""
    length = (summary.get("units") or {}).get("length", "")
    h_label = summary.get("h_label") or f"cell size h along the contact side [{length}]"
    paths = []
    for stem, x_key, xlabel, slopes in (
            ("refinement", "h", h_label, True),
            ("refinement_cost", "wall_s", "wall time of the level [s]", False)):
        paths += _error_figure(summary, outdir / stem, x_key, xlabel, slopes)
    return paths


def _error_figure(summary: dict, path: pathlib.Path, x_key: str, xlabel: str, slopes: bool) -> list[pathlib.Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    rows = summary["rows"]
    series = summary.get("convergence", {}).get("series", {})
    keys = present(rows)
    ncol = min(3, max(len(keys), 1))
    nrow = max(1, -(-len(keys) // ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.7 * ncol, 4.3 * nrow), squeeze=False)
    for ax in list(axes.ravel())[len(keys):]:
        ax.set_visible(False)
    for ax, key in zip(axes.ravel(), keys):
        for k, ((deg, plane), rs) in enumerate(_series(rows).items()):
            pts = [(r[x_key], r[f"err_{key}"], level_label(r, short=True)) for r in rs
                   if r.get(f"err_{key}") is not None and r[f"err_{key}"] > 0 and r.get(x_key)]
            if not pts:
                continue
            x, e, nx = zip(*pts)
            label = f"{series_name(deg, rows)} {plane}"
            est = (series.get(label) or {}).get(key, {})
            fitted, note = est.get("fitted"), est.get("note", "")
            if slopes and note.startswith(("oscillating", "differences do not decrease")):
                label += ", " + note.split(" (")[0].split(":")[0] + ": no slope"      # a slope would mean nothing
            elif slopes and fitted is not None:
                label += f", slope {fitted:.2f}"
            ax.loglog(x, e, "o-" if deg == 1 else "s--", color=f"C{k % 10}", label=label)
            for xi, ei, ni in pts:
                ax.annotate(str(ni), (xi, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.set_title(PLOT_TITLES.get(key, QOIS[key][0]), fontsize=10)
        ax.set_xlabel(xlabel, fontsize=9)
        ax.set_ylabel("relative error against the reference", fontsize=9)
        for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            if hi / lo < 100:       # under two decades: plain labels at 1, 2, 5 x 10^k
                axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            else:                   # decades only, no crowded minor labels
                axis.set_major_locator(LogLocator(numticks=6))
            axis.set_minor_formatter(NullFormatter())
        ax.margins(x=0.1, y=0.1)                # room for the nx labels
        ax.tick_params(labelsize=8)
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    what = "the cell size (slopes: observed orders)" if slopes else "the wall time of the level (what accuracy costs)"
    by = "nx" if any(r.get("nx") is not None for r in rows) else "the size factor"
    fig.suptitle(f"{summary['scene']}: relative error against {what}\n(points labelled with {by})", fontsize=11)
    fig.tight_layout()
    out = [path.with_suffix(".png"), path.with_suffix(".svg")]
    for p in out:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return out


def write_outputs(summary: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    """Write the study's ``refinement.csv`` (unit in each header), ``refinement.md``, the plots and
    ``refinement.json`` (the whole summary) into ``outdir``; returns the paths written."""
    outdir.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.writer(buf)
    columns = csv_columns(summary["rows"])
    units = {**summary["units"], "h": summary.get("h_unit", summary["units"].get("length"))}
    w.writerow([csv_header(c, "h" if c == "h" else UNIT_OF.get(c), units) for c in columns])
    w.writerows([row.get(c, "") for c in columns] for row in summary["rows"])
    (outdir / "refinement.csv").write_text(buf.getvalue())
    (outdir / "refinement.md").write_text(markdown(summary))
    paths = [outdir / "refinement.csv", outdir / "refinement.md", *plot(summary, outdir)]
    (outdir / "refinement.json").write_text(json.dumps(summary, indent=1, default=str))
    return paths + [outdir / "refinement.json"]
