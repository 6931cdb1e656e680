"""Mesh-refinement study of a block scene: what accuracy costs (scene section ``refinement``).

The scene's block study runs at every mesh level (``nx`` cells along AB, ``ny = nx * height /
length`` so the cells stay square), every element degree and every plane model asked for. At
each level the quantities a user of a contact-stability study cares about are recorded with the
wall time of every stage:

- ``final_mu``: the smallest MCEIP-mu (21)-(23) at the final state of the path;
- ``first_mu_ux``: the CD displacement u_x of the first state (first distinct classification
  along the path) at which MCEIP-mu has a solution, with that solution (``first_mu``);
- ``lambda2``: the largest admissible lambda^2 of the sufficient condition (17)-(18) at the final
  state's classification with the friction coefficient ``mu_fixed``;
- ``depth``: the CD normal displacement giving the requested normal force (the compliance);
- ``tangential_resultant``: the tangential resultant on AB at CD u_x = -``resultant_at``;
- ``sliding_ux``: the CD u_x at which gross sliding starts (end of the path).

For each series (degree, plane) the observed order of convergence is estimated from the three
finest levels, ``p = log(|q3 - q2| / |q2 - q1|) / log(r)``, and, when the differences are
monotone with ``p > 0``, a Richardson-extrapolated reference ``q1 + (q1 - q2) / (r^p - 1)``;
otherwise the finest level is the reference and the note says why. Outputs (rank 0):
``refinement.csv`` (one row per level), ``refinement.json``, ``refinement.md`` (tables, orders,
the cheapest level reaching 10 %, 1 % and 0.1 %), ``refinement.png``/``.svg`` (relative error
against wall time, log-log: the accuracy-cost front) and each level's ``steps.csv``.

The first solution is found by scanning the distinct classifications along the path in order
(one MCEIP-mu search each, up to the first with a solution: ``first_solution: scan``), or not
at all (``none``). A bisection would be cheaper but assumes that once MCEIP-mu has a solution
it keeps having one along the path: this study shows that this is false on meshes finer than
the paper's (a solution with one slip node appears at the first slip, then disappears).
"""
from __future__ import annotations

import csv
import io
import json
import math
import pathlib
import time

import numpy as np
from mpi4py import MPI

from app.analyses.classify import FREE, SLIP, classify
from app.analyses.runner import analyse_state
from app.config import Scene
from app.progress import Progress

QOIS = {  # key: (label, unit)
    "final_mu": ("final-state smallest MCEIP-mu", "1"),
    "first_mu_ux": ("CD u_x at the first MCEIP-mu solution", "mm"),
    "lambda2": ("sufficient-condition lambda^2 at mu_fixed (final state)", "1/s^2"),
    "depth": ("CD depth for the normal force", "mm"),
    "tangential_resultant": ("tangential resultant at the fixed load", "N"),
    "sliding_ux": ("CD u_x at gross sliding", "mm"),
}
# Stages summed into the columns of the table (the rest is in 'other').
STAGE_GROUPS = {
    "t_mesh_assembly": ("mesh (gmsh)", "assemble stiffness", "assemble mass matrix"),
    "t_factor_W": ("factorise K, contact flexibility",),
    "t_loading": ("quasi-static loading",),
    "t_mceip_mu": ("condensed pencil", "contact Schur complement", "MCEIP-mu (21)-(23)"),
    "t_sufficient": ("reduced pencils", "sufficient condition (17)-(18)"),
}


def level_scene(scene: Scene, nx: int, degree: int, plane: str, **loading) -> Scene:
    """The scene at one mesh level (square cells), with the refinement section removed."""
    cfg = scene.system
    ny = max(1, int(round(nx * cfg.height / cfg.length)))
    system = cfg.model_copy(update={"nx": nx, "ny": ny, "degree": degree, "plane": plane})
    update = {"system": system, "refinement": None, "name": f"{scene.name}-P{degree}-{plane}-nx{nx}"}
    if loading:
        update["loading"] = scene.loading.model_copy(update=loading)
    return scene.model_copy(update=update)


def _mu_values(a: dict | None) -> list[float]:
    if not a or a.get("failed"):
        return []
    return sorted(s["value"] for s in a.get("solutions", []))


def _inspector(scene: Scene, ref):
    """The ``inspect`` hook of :func:`app.study.run_study` that computes the level's quantities
    (``scene``: the level's scene; ``ref``: the refinement section)."""
    mu_fixed = ref.mu_fixed if ref.mu_fixed is not None else scene.lambda2_mu
    scene_mu = scene.model_copy(update={"analyses": ["mceip_mu"]})
    scene_suff = scene.model_copy(update={"analyses": ["sufficient"], "mu": mu_fixed})

    def inspect(system, states, cache) -> dict:
        rtol = scene.settings.classify_rtol
        seen, order = {}, []
        for st in states:
            cls = classify(st, scene.mu, rtol)
            if cls.key not in seen:
                seen[cls.key] = cls
                if len(cls.slip) > 0:
                    order.append((st, cls))
        searched: dict = {}

        def mu_solutions(cls) -> list[float]:
            if cls.key not in searched:
                done = cache.get(cls.key)
                if done is not None and "mceip_mu" in done[1]:
                    searched[cls.key] = _mu_values(done[1]["mceip_mu"])
                else:
                    searched[cls.key] = _mu_values(analyse_state(system, cls, scene_mu).get("mceip_mu"))
            return searched[cls.key]

        out: dict = {"mu_fixed": mu_fixed, "distinct_with_slip": len(order),
                     "contact_nodes": len(system.nodes), "dofs": system.n_dofs}
        final = states[-1]
        fcls = classify(final, scene.mu, rtol)
        out["final_label"] = fcls.label()
        vals = mu_solutions(fcls) if len(fcls.slip) else []
        out["final_mu"] = vals[0] if vals else None
        out["final_mu_count"] = len(vals)

        # First distinct classification along the path with an MCEIP-mu solution.
        first, checked = None, 0
        if ref.first_solution == "scan":
            for i, (_, cls) in enumerate(order):
                checked += 1
                if mu_solutions(cls):
                    first = i
                    break
        out["first_method"] = f"{ref.first_solution}: {checked} of {len(order)} classifications searched"
        if first is not None:
            st, cls = order[first]
            out.update(first_mu_ux=float(st.load["u_x"]), first_mu=mu_solutions(cls)[0],
                       first_mu_state=st.index, first_mu_label=cls.label())
        else:
            out.update(first_mu_ux=None, first_mu=None, first_mu_state=None, first_mu_label=None)

        # Sufficient condition at mu_fixed on the final state's classification.
        lam = None
        if len(fcls.slip):
            a = analyse_state(system, fcls, scene_suff).get("sufficient", {})
            out["lambda2_eigensolver"] = a.get("eigensolver", a.get("reason"))
            lam = max(a["lambda2"]) if a.get("lambda2") else None
        out["lambda2"] = lam

        # Resultants at the fixed load and the load at gross sliding.
        tang = [s for s in states if s.load.get("phase") == "tangential"]
        out["tangential_resultant"] = None
        if tang:
            best = min(tang, key=lambda s: abs(abs(s.load["u_x"]) - ref.resultant_at))
            if abs(abs(best.load["u_x"]) - ref.resultant_at) <= 0.5 * scene.loading.tangential_step + 1e-12:
                out["tangential_resultant"] = float(best.load["tangential_resultant"])
                out["normal_resultant"] = float(best.load["normal_resultant"])
        contact = [s for s in fcls.status if s != FREE]
        out["sliding_ux"] = (float(final.load["u_x"]) if final.load.get("phase") == "tangential" and contact
                             and all(s == SLIP for s in contact) else None)
        return out

    return inspect


def _stage_times(stages: list[dict]) -> dict:
    out = {k: 0.0 for k in STAGE_GROUPS}
    out["t_other"] = 0.0
    for st in stages:
        for key, names in STAGE_GROUPS.items():
            if st["name"] in names:
                out[key] += st["seconds"]
                break
        else:
            out["t_other"] += st["seconds"]
    return out


def run_level(scene: Scene, nx: int, degree: int, plane: str, comm: MPI.Comm,
              progress: Progress | None = None) -> tuple[dict, dict]:
    """One level: returns (the row of refinement.csv, the study's results)."""
    from app.study import run_study
    lvl = level_scene(scene, nx, degree, plane)
    t0 = time.perf_counter()
    res = run_study(lvl, comm, progress, inspect=_inspector(lvl, scene.refinement))
    wall = time.perf_counter() - t0
    q = res["inspection"]
    n_contact, n_dofs = q["contact_nodes"], q["dofs"]
    row = {"degree": degree, "plane": plane, "pattern": lvl.system.pattern, "nx": nx, "ny": lvl.system.ny,
           "h_mm": lvl.system.length / nx, "contact_nodes": n_contact, "dofs": n_dofs,
           "states": len(res["states"]), "distinct": res["distinct_classifications"],
           "depth": res["path"].get("normal_displacement_mm"),
           **{k: q.get(k) for k in ("final_mu", "first_mu_ux", "first_mu", "lambda2",
                                    "tangential_resultant", "sliding_ux")},
           "first_mu_label": q.get("first_mu_label"), "final_label": q.get("final_label"),
           "first_method": q.get("first_method"), "path_end": res["path"].get("end"),
           "wall_s": wall, **_stage_times(res["stages"])}
    return row, res


# -- convergence ---------------------------------------------------------------------------------
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
    out: dict = {}
    for r in rows:
        out.setdefault((r["degree"], r["plane"]), []).append(r)
    return {k: sorted(v, key=lambda r: r["nx"]) for k, v in out.items()}


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
        conv["series"][f"P{deg} {plane}"] = {
            key: observed_order([r["h_mm"] for r in rs], [r.get(key) for r in rs]) for key in QOIS}
    for plane in dict.fromkeys(p for _, p in series):
        degs = sorted((d for d, p in series if p == plane), reverse=True)
        conv["reference"][plane] = {}
        for key in QOIS:
            ref = None
            for d in degs:
                e = conv["series"][f"P{d} {plane}"][key]
                if e["richardson"] and e["p"] is not None and e["p"] >= 0.5:
                    ref = {"value": e["reference"], "from": f"P{d} Richardson (p = {e['p']:.2f})"}
                    break
            if ref is None:
                for d in degs:
                    vals = [r for r in series[(d, plane)] if r.get(key) is not None]
                    if vals:
                        fin = min(vals, key=lambda r: r["h_mm"])
                        ref = {"value": fin[key], "from": f"finest P{d} level (nx = {fin['nx']}; no trusted "
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
CSV_COLUMNS = ["degree", "plane", "pattern", "nx", "ny", "h_mm", "contact_nodes", "dofs", "states", "distinct",
               *QOIS, "first_mu", "first_mu_label", "final_label",
               *[f"err_{k}" for k in QOIS], "wall_s", *STAGE_GROUPS, "t_other", "first_method", "path_end"]


def _fmt(v, digits: int = 6) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def markdown(summary: dict) -> str:
    rows, conv = summary["rows"], summary["convergence"]
    lines = [f"# Refinement study: {summary['scene']}", "",
             f"{summary['system']}; mu = {summary['mu']}, sufficient condition at mu_fixed = {summary['mu_fixed']}; "
             f"{summary['mpi_ranks']} MPI rank(s); total {summary['wall_seconds']:.1f} s.", ""]
    for (deg, plane), rs in _series(rows).items():
        lines += [f"## P{deg}, plane {plane}", "",
                  "| nx x ny | contact nodes | DOFs | final MCEIP-mu | first solution at CD u_x [mm] (mu) | "
                  "lambda^2 [1/s^2] | depth [mm] | T at fixed load [N] | gross sliding u_x [mm] | wall [s] | "
                  "MCEIP-mu [s] | factor K + W [s] | loading [s] |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rs:
            lines.append(f"| {r['nx']} x {r['ny']} | {r['contact_nodes']} | {r['dofs']} | {_fmt(r['final_mu'])} | "
                         f"{_fmt(r['first_mu_ux'], 4)} ({_fmt(r['first_mu'], 5)}) | {_fmt(r['lambda2'], 5)} | "
                         f"{_fmt(r['depth'], 6)} | {_fmt(r['tangential_resultant'], 6)} | {_fmt(r['sliding_ux'], 4)} | "
                         f"{r['wall_s']:.2f} | {r['t_mceip_mu']:.2f} | {r['t_factor_W']:.2f} | {r['t_loading']:.2f} |")
        lines += ["", "| quantity | observed order p (3 finest) | fitted slope | reference | note |",
                  "|---|---|---|---|---|"]
        for key, (label, unit) in QOIS.items():
            e = conv["series"][f"P{deg} {plane}"][key]
            lines.append(f"| {label} [{unit}] | {_fmt(e['p'], 3)} | {_fmt(e['fitted'], 3)} | "
                         f"{_fmt(e['reference'], 7)}{' (Richardson)' if e['richardson'] else ''} | {e['note']} |")
        lines.append("")
    for plane, refs in conv["reference"].items():
        lines += [f"## Plane {plane}: reference values and the cheapest level reaching an accuracy", "",
                  "Relative errors are measured against one reference per quantity (below); the cheapest level "
                  "is the one with the smallest wall time whose error is at most the target.", "",
                  "| quantity | reference | from | 10 % | 1 % | 0.1 % |", "|---|---|---|---|---|---|"]
        for key, (label, unit) in QOIS.items():
            ch = cheapest(rows, key, plane)
            cells = [f"P{r['degree']} nx={r['nx']} ({r['wall_s']:.1f} s)" if r else "not reached"
                     for r in ch.values()]
            lines.append(f"| {label} [{unit}] | {_fmt(refs[key]['value'], 7)} | {refs[key]['from']} | "
                         + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Why orders can be poor here", "",
              "- The contact zone ends at the corners A and B (and at the moving lift-off point), where the "
              "contact pressure is singular: reactions, compliance and eigenvalues converge below the "
              "smooth-problem orders (p ~ 1-1.5 instead of 2).",
              "- The final state is the state at gross sliding (or at tangential_max), which itself moves with "
              "the mesh (later gross sliding, more nodes lifted off): its critical mu mixes discretisation "
              "error with a change of state, so it may oscillate at the 1e-3 level.",
              "- The first state with an MCEIP-mu solution is a discrete event of the path (which node slips "
              "next, resolved to one tangential step): path dependence, not a convergent quantity.",
              "- Plane strain with nu near 0.5: P1 triangles lock (too stiff) and P2 converges slowly; values "
              "from these meshes may be far from the limit.", ""]
    if summary.get("skipped"):
        lines += ["Skipped: " + "; ".join(summary["skipped"])]
    return "\n".join(lines) + "\n"


def plot(summary: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = summary["rows"]
    keys = list(QOIS)
    fig, axes = plt.subplots(2, 3, figsize=(15, 9))
    for ax, key in zip(axes.ravel(), keys):
        for (deg, plane), rs in _series(rows).items():
            pts = [(r["wall_s"], r[f"err_{key}"], r["nx"]) for r in rs
                   if r.get(f"err_{key}") is not None and r[f"err_{key}"] > 0]
            if not pts:
                continue
            t, e, nx = zip(*pts)
            ax.loglog(t, e, "o-" if deg == 1 else "s--", label=f"P{deg} {plane}")
            for ti, ei, ni in pts:
                ax.annotate(str(ni), (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.set_title(QOIS[key][0], fontsize=10)
        ax.set_xlabel("wall time of the level [s]")
        ax.set_ylabel("relative error vs reference")
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(f"Accuracy against cost: {summary['scene']} (labels: nx)")
    fig.tight_layout()
    paths = [outdir / "refinement.png", outdir / "refinement.svg"]
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths


def write_outputs(summary: dict, outdir: pathlib.Path) -> list[pathlib.Path]:
    outdir.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    w.writeheader()
    w.writerows(summary["rows"])
    (outdir / "refinement.csv").write_text(buf.getvalue())
    (outdir / "refinement.md").write_text(markdown(summary))
    paths = [outdir / "refinement.csv", outdir / "refinement.md", *plot(summary, outdir)]
    (outdir / "refinement.json").write_text(json.dumps(summary, indent=1, default=str))
    return paths + [outdir / "refinement.json"]


def _warm_up(scene: Scene, comm: MPI.Comm) -> None:
    """Compile the forms of every degree (JIT) on the smallest level, so that the first level's
    wall time is not the compiler's."""
    from app.study import run_study
    ref = scene.refinement
    for deg in ref.degrees:
        lvl = level_scene(scene, ref.levels[0], deg, ref.planes[0],
                          tangential_max=scene.loading.tangential_step)
        run_study(lvl.model_copy(update={"analyses": ["sufficient"]}), comm)


def run_refinement(scene: Scene, comm: MPI.Comm, progress: Progress | None = None,
                   outdir: pathlib.Path | None = None, log=print) -> dict:
    """Run every level; rank 0 writes the outputs into ``outdir``. Returns the summary."""
    from app.outputs.results import STEP_COLUMNS, step_rows
    ref = scene.refinement
    t0 = time.perf_counter()
    _warm_up(scene, comm)
    rows, failures, skipped = [], [], []
    for plane in ref.planes:
        for deg in ref.degrees:
            for nx in ref.levels:
                if ref.max_contact_nodes is not None and deg * nx + 1 > ref.max_contact_nodes:
                    if plane == ref.planes[0]:
                        skipped.append(f"P{deg} nx={nx} ({deg * nx + 1} contact nodes > max_contact_nodes = "
                                       f"{ref.max_contact_nodes})")
                    continue
                row, res = run_level(scene, nx, deg, plane, comm, progress)
                rows.append(row)
                failures += [{**f, "level": f"P{deg} {plane} nx={nx}"} for f in res["failures"]]
                if comm.rank == 0:
                    log(f"refinement: P{deg} {plane} nx={nx}: {row['dofs']} DOFs, {row['contact_nodes']} contact nodes, "
                        f"final mu {_fmt(row['final_mu'])}, first at u_x {_fmt(row['first_mu_ux'], 4)}, "
                        f"lambda^2 {_fmt(row['lambda2'], 5)}, {row['wall_s']:.1f} s")
                    if outdir is not None:
                        d = outdir / "levels" / f"P{deg}-{plane}-nx{nx}"
                        d.mkdir(parents=True, exist_ok=True)
                        buf = io.StringIO()
                        w = csv.DictWriter(buf, fieldnames=STEP_COLUMNS, extrasaction="ignore")
                        w.writeheader()
                        w.writerows(step_rows(res))
                        (d / "steps.csv").write_text(buf.getvalue())
    conv = analyse_convergence(rows)
    cfg = scene.system
    summary = {"scene": scene.name, "mu": scene.mu,
               "mu_fixed": ref.mu_fixed if ref.mu_fixed is not None else scene.lambda2_mu,
               "system": (f"block {cfg.length}x{cfg.height}x{cfg.thickness} mm, {cfg.pattern}, E={cfg.E} MPa, "
                          f"nu={cfg.nu}, loading {scene.loading.model_dump()}"),
               "levels": ref.levels, "degrees": ref.degrees, "planes": ref.planes,
               "mpi_ranks": comm.size, "rows": rows, "convergence": conv, "failures": failures, "skipped": skipped,
               "wall_seconds": time.perf_counter() - t0, "quantities": {k: v[0] for k, v in QOIS.items()}}
    if comm.rank == 0 and outdir is not None:
        summary["files"] = [str(p) for p in write_outputs(summary, outdir)]
    return summary


def main(scene: Scene, args, comm: MPI.Comm, folder, outdir: pathlib.Path) -> int:
    """``python -m app run`` of a scene with a ``refinement`` section (called by app/cli.py)."""
    from app.errors import UnreachableLoad
    quiet = getattr(args, "quiet", False)
    try:
        summary = run_refinement(scene, comm, Progress(enabled=False, comm=comm), outdir,
                                 log=(lambda *a: None) if quiet else (lambda *a: print(*a, flush=True)))
    except UnreachableLoad as err:   # raised identically on every rank
        if comm.rank == 0:
            import sys
            print(f"error: {getattr(args, 'scene', None) or 'scene'}: loading: {err}", file=sys.stderr)
        return 2
    comm.Barrier()                                            # MPI collective: rank 0 has written
    if comm.rank == 0:
        final = folder.commit()
        if not quiet:
            print(f"refinement study '{scene.name}': {len(summary['rows'])} levels in "
                  f"{summary['wall_seconds']:.1f} s; results in {final}/ (refinement.md, refinement.csv, "
                  f"refinement.png)")
    return 3 if summary["failures"] else 0
