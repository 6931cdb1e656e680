"""report.md: one page per study tying together the summary table, the plots, the screenshots,
the ParaView files, the scene and the versions used."""
from __future__ import annotations

import datetime
import math
import pathlib

import yaml

from app.io.result import Load, MceipResult, StateResult, StudyResult
from app.io.select import describe

PLOT_CAPTIONS = {
    "status_map": "Contact status of every node of AB (rows, A at the bottom) against the load step: "
                  "slip spreading along the contact side.",
    "reactions": "Normal and tangential reactions along AB at the pictured states; dashed: the Coulomb "
                 "limits +-mu |r_N|, squares: slip nodes (on the limit).",
    "mceip_mu": "Smallest critical friction coefficient (MCEIP-mu) at each state (grey dots: every value "
                "found) and the number of slip nodes; the dashed line is the scene's mu.",
    "necessary": "Smallest eigenvalue of sym K*(mu): the necessary condition (19) for divergence holds "
                 "where it is <= 0 (shaded).",
}


GENERIC_CAPTIONS = {     # a body other than the built-in block: no side AB, no CD
    "status_map": "Contact status of every contact node (rows, ordered by their tangential coordinate s "
                  "along the obstacle) against the load step: slip spreading along the contact boundary.",
    "reactions": "Normal and tangential reactions (in each node's own obstacle frame) against the contact "
                 "nodes' tangential coordinate s along the obstacle at the pictured states; dashed: the "
                 "Coulomb limits +-mu |r_N|, squares: slip nodes (on the limit).",
}


def _block_like(study: StudyResult) -> bool:
    """The contact side is the block's AB (captions name AB and CD), from the registered system type."""
    from app.systems import SYSTEM_TYPES
    kind = SYSTEM_TYPES.get((study.scene_config.get("system") or {}).get("type", "block"))
    return kind is not None and kind.contact_line == "AB"


def _load_label(load: Load) -> str:
    """A loading program's state: phase name and step (the block's states give CD u_x instead).
    The phase's name is a key of the loading program's own (``model_extra``)."""
    name = (load.model_extra or {}).get("name")
    phase = "" if load.phase is None else load.phase
    step = "" if load.step is None else load.step
    return f"{name or phase} {step}".strip()


def versions() -> dict:
    """Versions of the software a run used (read from package metadata and loaded modules)."""
    import importlib.metadata as md
    import platform
    import sys
    out = {"python": platform.python_version()}
    for name in ("contact-divergence", "fenics-dolfinx", "petsc4py", "slepc4py", "mpi4py", "numpy", "scipy",
                 "pydantic", "matplotlib", "pyvista", "vtk", "meshio", "h5py", "gmsh"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            pass
    for mod, key in (("dolfinx", "fenics-dolfinx"), ("gmsh", "gmsh")):
        m = sys.modules.get(mod)
        if key not in out and m is not None and getattr(m, "__version__", None):
            out[key] = str(m.__version__)
    for mod, key, variable in (("gmsh", "gmsh", "GMSH_API_VERSION"),):
        if key not in out:      # not imported (a cached mesh is read without gmsh): from its source
            version = _source_version(mod, variable)
            if version:
                out[key] = version
    try:
        from petsc4py import PETSc
        out["PETSc"] = ".".join(str(v) for v in PETSc.Sys.getVersion())
    except Exception:  # pragma: no cover - PETSc is always there in this app
        pass
    return out


def _source_version(module: str, variable: str) -> str | None:
    """The string ``variable = "..."`` of an installed module's source, without importing it
    (importing gmsh costs 0.2-0.4 s); None if not found."""
    import importlib.util
    import re
    try:
        spec = importlib.util.find_spec(module)
        text = pathlib.Path(spec.origin).read_text(errors="replace") if spec and spec.origin else ""
    except (ImportError, OSError, ValueError):
        return None
    m = re.search(rf'^{re.escape(variable)}\s*=\s*"([^"]+)"', text, re.M)
    return m.group(1) if m else None


def _fmt(v, spec: str = ".6g") -> str:
    if v is None or v == "":
        return ""
    if isinstance(v, str):
        return v
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    return format(v, spec)


def _pattern(pattern) -> str:
    """A mode's pattern as one letter per slip node: ``S`` slips in the mode, ``-`` is stuck in it."""
    return "".join("S" if p == "slip" else "-" for p in pattern)


def _solutions(a: MceipResult | None, slip_nodes: int) -> str:
    """An MCEIP analysis in a table cell: its solutions ``value (pattern)`` and what is proven of
    them, ``failed``, ``n/a``, ``none (no slip node)`` at a state without unknowns, or empty when
    it was not computed."""
    if a is None:
        return ""
    if a.failed:
        return "failed"
    if a.not_applicable:
        return "n/a"
    if slip_nodes == 0:
        return "none (no slip node)"
    rigorous = a.certificate is None or a.certificate.rigorous is not False
    onset = getattr(a, "onset", None)
    word = ("proven" if rigorous else "shown in floating point, not a rigorous proof") if a.certified else \
        "onset proven" if onset is not None and onset.proven else "found (not proven)"
    if not a.solutions:
        return f"none ({word})"
    return f"{word}: " + ", ".join(f"{_fmt(s.value)} ({_pattern(s.pattern)})" for s in a.solutions)


def _is_number(v) -> bool:
    return isinstance(v, (int, float))


def _unanswered(a) -> str | None:
    """The cell of an analysis that gave no answer (``failed``, ``n/a``), None when it answered."""
    return "failed" if a.failed else ("n/a" if a.not_applicable else None)


def _necessary_cell(st: StateResult) -> str:
    nec = st.analyses.necessary
    if nec is None:
        return ""
    return _unanswered(nec) or f"{_fmt(nec.min_eig_K_sym, '.4g')}" + (" (holds)" if nec.satisfied else "")


def _sufficient_cell(st: StateResult) -> str:
    suf = st.analyses.sufficient
    if suf is None:
        return "none"
    return _unanswered(suf) or ", ".join(_fmt(float(v)) for v in suf.lambda2) or "none"


def summary_table(study: StudyResult) -> list[str]:
    """One row per distinct classification (its first state and the range of states sharing it)."""
    states = study.states
    groups: dict[int, list[StateResult]] = {}
    for s in states:
        first = s.index if s.analyses_shared_with is None else s.analyses_shared_with
        groups.setdefault(first, []).append(s)
    asked = study.analyses_requested
    length = study.units.length
    program = not any(_is_number(s.load.u_x) for s in states) and any(s.load.step is not None for s in states)
    head = ["states", "load (phase step)" if program else f"CD u_x [{length}]", "stick / slip / free"]
    if "necessary" in asked:
        head.append("min eig sym K* (19)")
    if "sufficient" in asked:
        head.append("sufficient (17)-(18): lambda^2")
    if "mceip_mu" in asked:
        head.append("MCEIP-mu (pattern A to B)" if _block_like(study) else "MCEIP-mu (pattern along s)")
    if "mceip_lambda2" in asked:
        head.append("MCEIP-lambda^2")
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for first, members in groups.items():
        s0 = members[0]
        ids = [m.index for m in members]
        rng = f"{ids[0]}" if len(ids) == 1 else f"{ids[0]}-{ids[-1]}" if ids == list(range(ids[0], ids[-1] + 1)) \
            else f"{ids[0]}, ... ({len(ids)})"
        ux = [m.load.u_x for m in members if _is_number(m.load.u_x)]
        uxs = "" if not ux else (_fmt(ux[0], ".4g") if len(ux) == 1 or ux[0] == ux[-1]
                                  else f"{_fmt(ux[0], '.4g')} to {_fmt(ux[-1], '.4g')}")
        if program:
            labels = [_load_label(m.load) for m in members]
            uxs = labels[0] if len(labels) == 1 else f"{labels[0]} to {labels[-1]}"
        c = s0.classification
        row = [rng, uxs, f"{c.stick} / {c.slip} / {c.free}" + (f" / {c.zero} zero" if c.zero else "")]
        if "necessary" in asked:
            row.append(_necessary_cell(s0))
        if "sufficient" in asked:
            row.append(_sufficient_cell(s0))
        if "mceip_mu" in asked:
            row.append(_solutions(s0.analyses.mceip_mu, s0.classification.slip))
        if "mceip_lambda2" in asked:
            row.append(_solutions(s0.analyses.mceip_lambda2, s0.classification.slip))
        rows.append("| " + " | ".join(row) + " |")
    return rows


def _rel(path: pathlib.Path, outdir: pathlib.Path) -> str:
    try:
        return path.relative_to(outdir).as_posix()
    except ValueError:
        return str(path)


def write_report(study: StudyResult, outdir: pathlib.Path, pictured: list[int], plot_files: list[pathlib.Path],
                 shot_files: list[pathlib.Path], notes: list[str]) -> pathlib.Path:
    """``report.md`` in ``outdir``: the study in brief, the classifications, the pictures, the
    ParaView files, notes, stages, the scene and the versions."""
    cfg = study.scene_config
    block = _block_like(study)
    body = "block" if block else "body"
    modes = (study.outputs.modes if study.outputs is not None else None) or []
    modes_built = sorted({m.built for m in modes})
    L = _overview(study) + _classifications(study)
    if plot_files:
        L += _plots(plot_files, outdir, block)
    if shot_files:
        L += _screenshots(shot_files, outdir, cfg.get("outputs") or {}, pictured, body, modes_built)
    L += _paraview(study, body, modes_built)
    L += _closing(study, cfg, notes)
    path_out = outdir / "report.md"
    path_out.write_text("\n".join(L) + "\n", encoding="utf-8")
    return path_out


def _overview(study: StudyResult) -> list[str]:
    """The title and the study in a few lines (states, first instability, final state, failures)."""
    L: list[str] = []
    L += [f"# Study report: {study.scene}", ""]
    L += [f"{study.system}; mu = {study.mu}; analyses: "
          f"{', '.join(study.analyses_requested)}; MPI ranks: {study.mpi_ranks}.", ""]
    L += [f"- {len(study.states)} equilibrium state(s), {study.distinct_classifications} distinct "
          f"classification(s); the path ended: {study.path.end}."]
    first_mu = study.first_instability()
    if first_mu is not None:
        c = first_mu.classification
        vals = ", ".join(_fmt(float(v)) for v in first_mu.mu_values())
        L.append(f"- MCEIP-mu first has a solution at state {first_mu.index} ({c.stick} stick / "
                 f"{c.slip} slip / {c.free} free): mu = {vals}.")
    last = study.final
    if last.analyses.mceip_mu is not None:
        L.append(f"- final state {last.index}: MCEIP-mu {_solutions(last.analyses.mceip_mu, last.classification.slip)}.")
    blocks = [getattr(last.analyses, k) for k in type(last.analyses).model_fields]
    na = next((a.reason for a in blocks if a is not None and a.not_applicable), None)
    if na:
        L.append(f"- stability analyses at the final state: {na}.")
    if study.failures:
        L.append(f"- **incomplete**: {len(study.failures)} failure(s): " + "; ".join(
            f"state {f.state}: {f.reason}" for f in study.failures[:5]))
    for w in study.warnings:
        L.append(f"- warning: {w}")
    L += [f"- wall time {_fmt(study.wall_seconds, '.2f')} s. Units: "
          + ", ".join(f"{k} {v}" for k, v in study.units.to_dict().items()) + ".", ""]
    return L


def _classifications(study: StudyResult) -> list[str]:
    """The table of distinct classifications."""
    L: list[str] = []
    L += ["## Distinct classifications", "",
          "Analyses depend only on the classification, so each row is computed once, at its first state, "
          "and shared by the others. Patterns list the slip nodes "
          + ("from A to B" if _block_like(study) else "in the order of the contact nodes")
          + ": `S` slips in the mode, "
          "`-` is stuck in it. Full numbers: `results.json`, one row per state: `steps.csv`.", ""]
    L += summary_table(study) + [""]
    return L


def _plots(plot_files: list[pathlib.Path], outdir: pathlib.Path, block: bool) -> list[str]:
    """The plots with their captions."""
    L: list[str] = []
    L += ["## Plots", ""]
    for p in plot_files:
        if p.suffix != ".png":
            continue
        L += [f"![{p.stem}]({_rel(p, outdir)})", "", f"*{(PLOT_CAPTIONS if block else {**PLOT_CAPTIONS, **GENERIC_CAPTIONS}).get(p.stem, p.stem)}* "
              f"(also [{p.with_suffix('.svg').name}]({_rel(p.with_suffix('.svg'), outdir)}))", ""]
    return L


def _screenshots(shot_files: list[pathlib.Path], outdir: pathlib.Path, out: dict, pictured: list[int], body: str,
                 modes_built: list[str]) -> list[str]:
    """The screenshots with their captions."""
    L: list[str] = []
    L += ["## Screenshots", "", "Pictured states: " + ", ".join(describe(s) for s in out.get("states", []))
          + f" -> states {', '.join(str(i) for i in pictured)}.", ""]
    if any(p.name.startswith("mode_") for p in shot_files):
        L += [f"Mode shapes (drawn with the largest displacement at 12 % of the {body}'s smaller side): "
              + "; ".join(modes_built) + ".", ""]
    for p in shot_files:
        kind = "state" if p.name.startswith("state_") else ("animation" if p.suffix == ".gif" else "mode")
        cap = {"state": f"The {body} at this state (contact nodes marked by status; grey: the obstacle; thin line: "
                        f"the undeformed {body}).",
               "mode": "Divergence mode (shape scaled to fit; contact nodes marked; black: slip nodes stuck in the mode).",
               "animation": "The mode growing as the divergence it predicts, a0 exp(lambda t) from 5 % to the drawn "
                            "amplitude (the time in the title; linearly for MCEIP-mu's static mode)."}[kind]
        L += [f"![{p.stem}]({_rel(p, outdir)})", "", f"*{p.stem}*: {cap}", ""]
    return L


def _paraview(study: StudyResult, body: str, modes_built: list[str]) -> list[str]:
    """What the ParaView files hold, when they were written."""
    L: list[str] = []
    files = study.outputs.files if study.outputs is not None else []
    if any(f.startswith("paraview/") for f in files):
        L += ["## ParaView files", "",
              "- `paraview/states.xdmf` (+ `states.h5`): every equilibrium state, time = state index. "
              "Fields: `displacement` (apply *Warp By Vector*), `von_mises` (cells), and at the contact "
              "nodes `contact_status` (-1 not a contact node, 0 free, 1 zero, 2 stick, 3 slip), `reaction` "
              f"(contact force on the {body}, global x/y) and `slip_direction` (unit vector of impending slip "
              "along the node's obstacle tangent, global x/y).",
              "- `paraview/modes.vtu`: every divergence mode found, one point field per mode, named "
              "`s<state>_<problem>_<k>_<value>`, normalised to max |v| = 1.", ""]
        if modes_built:
            L += ["Mode fields: " + "; ".join(modes_built) + ".", ""]
    return L


def _closing(study: StudyResult, cfg: dict, notes: list[str]) -> list[str]:
    """Notes, stages, the scene, the versions and the time of writing."""
    L: list[str] = []
    if notes:
        L += ["## Notes", ""] + [f"- {n}" for n in notes] + [""]

    L += ["## Stages", "", "| stage | seconds | count |", "|---|---|---|"]
    for st in study.stages:
        L.append(f"| {st.name} | {_fmt(st.seconds, '.3f')} | {st.count} |")
    L += [""]

    L += ["## Scene", "", "```yaml", yaml.safe_dump(cfg, sort_keys=False, default_flow_style=None).rstrip(), "```", ""]
    vers = study.versions or {}
    if vers:
        L += ["## Versions", "", "| software | version |", "|---|---|"]
        L += [f"| {k} | {v} |" for k, v in vers.items()] + [""]
    L += [f"Report written {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}."]
    return L
