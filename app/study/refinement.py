"""Mesh-refinement study of a meshed body: what accuracy costs (scene section ``refinement``).

The scene's study runs at every mesh level, every element degree and every plane model asked
for. The block's levels are ``levels`` (``nx`` cells along AB, ``ny = nx * height / length`` so
the cells stay square); a Gmsh body's are ``size_factors``, its .geo's characteristic lengths
times each factor (``system.mesh_size_factor``; each level's scene is validated again, so the
body is meshed, checked and limited as any scene's), and its cell size is measured relative to
the .geo's (h = the factor). At each level the quantities a user of a contact-stability study
cares about are recorded with the wall time of every stage:

- ``final_mu``: the smallest MCEIP-mu (21)-(23) at the final state of the path;
- ``first_mu_ux``: the CD displacement u_x of the first state (first distinct classification
  along the path) at which MCEIP-mu has a solution, with that solution (``first_mu``);
- ``lambda2``: the largest admissible lambda^2 of the sufficient condition (17)-(18) at the final
  state's classification with the friction coefficient ``mu_fixed``;
- ``depth``: the CD normal displacement giving the requested normal force (the compliance);
- ``tangential_resultant``: the tangential resultant on AB at CD u_x = -``resultant_at``;
- ``sliding_ux``: the CD u_x at which gross sliding starts (end of the path);
- for a loading program (a Gmsh body) instead of the block's CD quantities: ``first_mu_load``
  and ``sliding_load``, the load of those two states as the plots' x-axis measures it (the
  distance the program's load parameters travelled, app/io/select.py).

For each series (degree, plane) the observed order of convergence is estimated from the three
finest levels, ``p = log(|q3 - q2| / |q2 - q1|) / log(r)``, and, when the differences are
monotone with ``p > 0``, a Richardson-extrapolated reference ``q1 + (q1 - q2) / (r^p - 1)``;
otherwise the finest level is the reference and the note says why. Outputs (rank 0):
``refinement.csv`` (one row per level), ``refinement.json``, ``refinement.md`` (tables, orders,
the cheapest level reaching 10 %, 1 % and 0.1 %), ``refinement.png``/``.svg`` (relative error
against the cell size h, log-log, with each series' fitted slope), ``refinement_cost.png``/``.svg``
(relative error against wall time: the accuracy-cost front) and each level's ``steps.csv``.

The first solution is found by scanning the distinct classifications along the path in order
(one MCEIP-mu search each, up to the first with a solution: ``first_solution: scan``), or not
at all (``none``). A bisection would be cheaper but assumes that once MCEIP-mu has a solution
it keeps having one along the path: this study shows that this is false on meshes finer than
the paper's (a solution with one slip node appears at the first slip, then disappears).
"""
from __future__ import annotations

import json
import pathlib
import time

from mpi4py import MPI

from app.analyses.outcomes import MceipMuOutcome, Outcome, SufficientOutcome
from app.analyses.runner import analyse_state
from app.common.progress import Progress
from app.io.result import Stage, StudyResult
from app.io.select import program_load
from app.loading.classify import FREE, SLIP, classify, without_point_stick
from app.scene.schema import Scene, SceneError
from app.study.refinement_report import (  # noqa: F401 - observed_order re-exported
    QOIS,
    STAGE_GROUPS,
    analyse_convergence,
    fmt,
    observed_order,
    present,
    series_name,
    write_outputs,
)
from app.systems.units import CONTINUUM_UNITS


def level_scene(scene: Scene, level, degree: int, plane: str, short: bool = False) -> Scene:
    """The scene at one mesh level (the system's keys for it: the block's nx with square cells, a
    Gmsh body's size factor), validated again (a Gmsh body is meshed and checked as any scene's;
    its file path is absolute in the dump), with the refinement section removed; ``short``: one
    loading step only (the forms' compilation)."""
    from pydantic import ValidationError

    from app.scene.schema import format_error, scene_context
    cfg = scene.system
    data = json.loads(json.dumps(scene.model_dump(mode="json", exclude_unset=True, exclude={"refinement"})))
    data["name"] = f"{scene.name}-P{degree}-{plane}-{cfg.level_names(level)[1]}"
    data["system"].update(cfg.level_keys(level, degree, plane))
    if short:
        cfg.one_step(data)
    try:
        return Scene.model_validate(data, context=scene_context(data, None))
    except ValidationError as err:
        raise SceneError(f"refinement level {cfg.level_names(level)[0]}: {format_error(err)}") from None


def _sizes(cfg) -> tuple[int, int]:
    """(DOFs, contact nodes) of a level's system, as the pre-flight counts them (app/scene/limits.py)."""
    return cfg.mesh_sizes() if hasattr(cfg, "mesh_sizes") else cfg.file_sizes()[:2]


def _mu_values(a: Outcome | None) -> tuple[list[float], bool]:
    """The critical mu of an MCEIP-mu outcome, ascending (none when it failed or was not asked),
    and whether its smallest (the onset) is proven."""
    if not isinstance(a, MceipMuOutcome):
        return [], False
    return sorted(s.value for s in a.solutions), bool(a.onset is not None and a.onset.proven)


class _MuSearches:
    """MCEIP-mu of the classifications a level asks for, each searched once (or taken from the
    study's ``cache``): its values, ascending, and whether the smallest is proven."""

    def __init__(self, system, scene_mu: Scene, cache: dict):
        self.system, self.scene_mu, self.cache = system, scene_mu, cache
        self.searched: dict = {}

    def values(self, cls) -> list[float]:
        if cls.key not in self.searched:
            done = self.cache.get(cls.key)
            if done is not None and "mceip_mu" in done[1]:
                self.searched[cls.key] = _mu_values(done[1]["mceip_mu"])
            else:
                self.searched[cls.key] = _mu_values(analyse_state(self.system, cls, self.scene_mu).get("mceip_mu"))
        return self.searched[cls.key][0]

    def proven(self, cls) -> bool:
        return self.searched.get(cls.key, ([], False))[1]


def _final_mu(fcls, x: list[float], mu: _MuSearches) -> dict:
    """The final state's quantities: its smallest MCEIP-mu, and the same with its point stick zones
    slipping (stick zones one node wide, which the mesh does not resolve:
    :func:`app.loading.classify.without_point_stick`), each with whether it is proven."""
    vals = mu.values(fcls) if len(fcls.slip) else []
    out = {"final_label": fcls.label(), "final_mu": vals[0] if vals else None, "final_mu_count": len(vals),
           "final_mu_proven": bool(vals) and mu.proven(fcls)}
    point = without_point_stick(fcls, x)
    out["final_point_stick"] = 0 if point is None else sum(a != b for a, b in zip(fcls.status, point.status))
    if point is not None:
        vals = mu.values(point)
    out["final_mu_without_point_stick"] = vals[0] if vals else None
    out["final_mu_without_point_stick_proven"] = bool(vals) and mu.proven(fcls if point is None else point)
    return out


def _inspector(scene: Scene, ref):
    """The ``inspect`` hook of :func:`app.study.run.study` that computes the level's quantities
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
        mu_solutions = (mu := _MuSearches(system, scene_mu, cache)).values
        out: dict = {"mu_fixed": mu_fixed, "distinct_with_slip": len(order),
                     "contact_nodes": len(system.nodes), "dofs": system.n_dofs}
        fcls = classify(states[-1], scene.mu, rtol)
        out.update(_final_mu(fcls, [nd.x for nd in system.nodes], mu))

        # a loading program's load (its parameters' travel), where the states have parameters
        params = [st.load.get("parameters") for st in states]
        program = (program_load(params, CONTINUUM_UNITS[scene.units]) if all(p is not None for p in params)
                   else None)
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
            out.update(first_mu=mu_solutions(cls)[0], first_mu_state=st.index, first_mu_label=cls.label())
            if program is not None:
                out["first_mu_load"] = float(program[0][states.index(st)])
            elif st.load.get("u_x") is not None:
                out["first_mu_ux"] = float(st.load["u_x"])
        else:
            out.update(first_mu=None, first_mu_state=None, first_mu_label=None)

        # Sufficient condition at mu_fixed on the final state's classification.
        lam = None
        if len(fcls.slip):
            a = analyse_state(system, fcls, scene_suff).get("sufficient")
            ok = isinstance(a, SufficientOutcome)
            out["lambda2_eigensolver"] = a.eigensolver if ok else getattr(a, "reason", None)
            lam = max(a.lambda2) if ok and a.lambda2 else None
        out["lambda2"] = lam

        out.update(_load_quantities(scene, ref, states, fcls, program))
        return out

    return inspect


def _load_quantities(scene: Scene, ref, states: list, fcls, program) -> dict:
    """The resultants at the fixed load (the block's CD u_x = -``resultant_at``) and the load at
    gross sliding (the block's CD u_x; a loading program's load, ``program``: its axis and label)."""
    out: dict = {"tangential_resultant": None}
    tang = [s for s in states if s.load.get("phase") == "tangential"]
    if tang:
        best = min(tang, key=lambda s: abs(abs(s.load["u_x"]) - ref.resultant_at))
        if abs(abs(best.load["u_x"]) - ref.resultant_at) <= 0.5 * scene.loading.tangential_step + 1e-12:
            out["tangential_resultant"] = float(best.load["tangential_resultant"])
            out["normal_resultant"] = float(best.load["normal_resultant"])
    contact = [s for s in fcls.status if s != FREE]
    sliding = bool(contact) and all(s == SLIP for s in contact)
    final = states[-1]
    if program is not None:
        out["load_label"] = program[1]
        out["sliding_load"] = float(program[0][-1]) if sliding else None
    else:
        out["sliding_ux"] = (float(final.load["u_x"]) if final.load.get("phase") == "tangential" and sliding
                             else None)
    return out


def _stage_times(stages: list[Stage]) -> dict:
    """The study's stage times summed into the columns of :data:`STAGE_GROUPS` (the rest: ``t_other``)."""
    out = {k: 0.0 for k in STAGE_GROUPS}
    out["t_other"] = 0.0
    for st in stages:
        for key, names in STAGE_GROUPS.items():
            if st.name in names:
                out[key] += st.seconds
                break
        else:
            out["t_other"] += st.seconds
    return out


def run_level(scene: Scene, level, degree: int, plane: str, comm: MPI.Comm,
              progress: Progress | None = None, lvl: Scene | None = None) -> tuple[dict, StudyResult]:
    """One level (``level``: nx, or a Gmsh body's size factor; ``lvl``: its scene when already
    made): returns (the row of refinement.csv, the study's result)."""
    from app.study.run import study
    lvl = lvl if lvl is not None else level_scene(scene, level, degree, plane)
    t0 = time.perf_counter()
    res = study(lvl, comm, progress, inspect=_inspector(lvl, scene.refinement))
    wall = time.perf_counter() - t0
    q = res.inspection
    n_contact, n_dofs = q["contact_nodes"], q["dofs"]
    row = {"degree": degree, "element": getattr(lvl.system, "element", "displacement"), "plane": plane,
           **lvl.system.level_row(level), "contact_nodes": n_contact,
           "dofs": n_dofs, "states": len(res.states), "distinct": res.distinct_classifications,
           # the block's compliance (a loading program has its own load quantities instead)
           "depth": res.path.normal_displacement if q.get("load_label") is None else None,
           **{k: q.get(k) for k in ("final_mu", "final_mu_proven", "final_mu_without_point_stick",
                                    "final_mu_without_point_stick_proven", "final_point_stick", "first_mu_ux", "first_mu", "lambda2", "tangential_resultant",
                                    "sliding_ux", "first_mu_load", "sliding_load", "load_label")},
           "first_mu_label": q.get("first_mu_label"), "final_label": q.get("final_label"),
           "first_method": q.get("first_method"), "path_end": res.path.end,
           "wall_s": wall, **_stage_times(res.stages)}
    return row, res


# -- convergence ---------------------------------------------------------------------------------
def _warm_up(scene: Scene, comm: MPI.Comm) -> None:
    """Compile the forms of every degree (JIT) on the smallest level, so that the first level's
    wall time is not the compiler's."""
    from app.study.run import study
    ref = scene.refinement
    for deg in ref.degrees:
        lvl = level_scene(scene, ref.steps()[0], deg, ref.planes[0], short=True)
        study(lvl.model_copy(update={"analyses": ["sufficient"]}), comm)


def _levels(scene: Scene) -> dict:
    """Each level's scene per (degree, plane), validated up front (a Gmsh body is meshed at each
    size), and refused when a level is not finer than the one before (a .geo whose curves fix
    their node counts, ``Transfinite``, does not depend on its characteristic lengths)."""
    ref = scene.refinement
    out = {}
    for plane in ref.planes:
        for deg in ref.degrees:
            scenes = [level_scene(scene, lv, deg, plane) for lv in ref.steps()]
            sizes = [_sizes(s.system)[0] for s in scenes]
            for (l1, n1), (l2, n2) in zip(zip(ref.steps(), sizes), zip(ref.steps()[1:], sizes[1:])):
                if n2 <= n1:
                    name = scene.system.level_names
                    raise SceneError(
                        f"refinement.{scene.system.refinement_key}: the mesh has {n1} DOFs at {name(l1)[0]} and "
                        f"{n2} at {name(l2)[0]}: it does not get finer with the level (a .geo whose curves fix "
                        "their node counts, Transfinite, or whose sizes come from a field: refine it in the .geo, "
                        "or give a .geo that sets characteristic lengths)")
            out[(deg, plane)] = scenes
    return out


def run_refinement(scene: Scene, comm: MPI.Comm, progress: Progress | None = None,
                   outdir: pathlib.Path | None = None, log=print) -> dict:
    """Run every level; rank 0 writes the outputs into ``outdir``. Returns the summary."""
    from app.io.results import steps_csv
    ref = scene.refinement
    t0 = time.perf_counter()
    scenes = _levels(scene)
    _warm_up(scene, comm)
    rows, failures, skipped = [], [], []
    for plane in ref.planes:
        for deg in ref.degrees:
            for lv, lvl in zip(ref.steps(), scenes[(deg, plane)]):
                name, tag = scene.system.level_names(lv)
                n_contact = _sizes(lvl.system)[1]
                if ref.max_contact_nodes is not None and n_contact > ref.max_contact_nodes:
                    if plane == ref.planes[0]:
                        skipped.append(f"P{deg} {name} ({n_contact} contact nodes > max_contact_nodes = "
                                       f"{ref.max_contact_nodes})")
                    continue
                row, res = run_level(scene, lv, deg, plane, comm, progress, lvl=lvl)
                rows.append(row)
                failures += [{**f.to_dict(), "level": f"P{deg} {plane} {name}"} for f in res.failures]
                if comm.rank == 0:
                    first = (f"first at load {fmt(row['first_mu_load'], 4)}" if row.get("load_label")
                             else f"first at u_x {fmt(row['first_mu_ux'], 4)}")
                    point = (f" ({fmt(row['final_mu_without_point_stick'])} without its point stick zone)"
                             if row.get("final_point_stick") else "")
                    log(f"refinement: {series_name(deg, [row])} {plane} {name}: {row['dofs']} DOFs, "
                        f"{row['contact_nodes']} contact nodes, final mu {fmt(row['final_mu'])}{point}, {first}, "
                        f"lambda^2 {fmt(row['lambda2'], 5)}, {row['wall_s']:.1f} s")
                    if outdir is not None:
                        d = outdir / "levels" / f"P{deg}-{plane}-{tag}"
                        d.mkdir(parents=True, exist_ok=True)
                        (d / "steps.csv").write_text(steps_csv(res))
    conv = analyse_convergence(rows)
    units = dict(CONTINUUM_UNITS[scene.units])
    labels = {r["load_label"] for r in rows if r.get("load_label")}
    if len(labels) == 1:          # a program's load: its unit from the axis label ("... [mm]")
        units["load"] = labels.pop().rsplit("[", 1)[-1].rstrip("]")
    summary = {"scene": scene.name, "mu": scene.mu,
               "mu_fixed": ref.mu_fixed if ref.mu_fixed is not None else scene.lambda2_mu,
               "units": units, "system": scene.system.describe(units)
               + (f", loading {scene.loading.model_dump()}" if scene.loading is not None else ""),
               "levels": ref.steps(), "degrees": ref.degrees, "planes": ref.planes,
               "mpi_ranks": comm.size, "rows": rows, "convergence": conv, "failures": failures, "skipped": skipped,
               "wall_seconds": time.perf_counter() - t0,
               "quantities": {k: QOIS[k][0] for k in present(rows)}}
    h_words, h_quantity = scene.system.refinement_h
    h_unit = units.get(h_quantity) if h_quantity else None
    summary.update(h_label=f"{h_words} [{h_unit}]" if h_unit else h_words, h_unit=h_unit or "1")
    if comm.rank == 0 and outdir is not None:
        summary["files"] = [str(p) for p in write_outputs(summary, outdir)]
    return summary


def main(scene: Scene, args, comm: MPI.Comm, folder, outdir: pathlib.Path) -> int:
    """``python -m app run`` of a scene with a ``refinement`` section (called by app/cli/main.py)."""
    from app.common.errors import UnreachableLoad, fail
    from app.study import driver
    quiet = getattr(args, "quiet", False)
    try:
        summary = run_refinement(scene, comm, Progress(enabled=False, comm=comm), outdir,
                                 log=(lambda *a: None) if quiet else (lambda *a: print(*a, flush=True)))
    except UnreachableLoad as err:   # raised identically on every rank
        return fail(driver.loading_error(getattr(args, "scene", None) or "scene", err))
    final = driver.commit(folder, comm)                       # MPI collective: rank 0 has written
    if comm.rank == 0 and not quiet:
        print(f"refinement study '{scene.name}': {len(summary['rows'])} levels in "
              f"{summary['wall_seconds']:.1f} s; results in {final}/ (refinement.md, refinement.csv, "
              f"refinement.png, refinement_cost.png)")
    return driver.exit_status(summary["failures"])
