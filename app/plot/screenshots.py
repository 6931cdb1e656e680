"""Off-screen pyvista pictures of the body (no display or X server needed).

* ``state_XXXX_<field>.png``: the body deformed at a pictured state (true scale unless
  ``screenshots.scale``), coloured by |u| or the von Mises stress with a colour bar, the
  undeformed outline (the mesh's boundary edges), the obstacle (a hatched strip along its line,
  on the side its normal points to), and the contact nodes marked by status;
* ``mode_<name>.png``: a divergence mode drawn like the paper's Figs. 2-3: the mesh displaced by
  the mode shape (scaled to fit), coloured by the mode amplitude, the contact nodes marked (stick,
  slip nodes that slip in the mode, slip nodes stuck in the mode, free), eigenvalue in the title.

Nothing assumes a rectangle or a horizontal contact side: the geometry comes from the mesh, the
contact nodes and the obstacle line saved in fields.npz.
Drawn from ``fields/fields.npz`` and the study's results (a
[`StudyResult`][app.io.result.StudyResult]) only, so ``python -m app render`` redraws them.

In a process that has loaded DOLFINx the drawing runs in a child process (app/plot/worker.py,
started by app/plot/pictures.py): DOLFINx switches the
interpreter to RTLD_GLOBAL library loading, after which VTK's scalar bar aborts the process
(conflicting C++ template symbols). The child also keeps a rendering failure (no EGL/OSMesa on
the machine, say) from taking the study's results with it.
"""
from __future__ import annotations

import os
import pathlib
import sys

import numpy as np

from app.io.result import Load, StateResult, StudyResult, Units
from app.plot.canvas import (
    FieldData,
    add_body,
    bar_args,
    close_plotters,
    finish,
    font_size,
    import_pyvista,
    markers,
    plotter,
    text,
    truetype_font,
)

PROBLEM_TITLE = {"mceip_mu": "MCEIP-\u03bc mode: \u03bc", "mceip_lambda2": "MCEIP-\u03bb\u00b2 mode: \u03bb\u00b2",
                 "sufficient": "sufficient condition (17)-(18) mode: \u03bb\u00b2"}


def _unit(value: str | None, default: str) -> str:
    """A unit name of the study's ``units``, ``default`` when the system has none."""
    return default if value is None else value


def _where(load: Load, units: Units | dict) -> str:
    """Where a state is on the loading path, for a picture's title: the block's CD displacement,
    or a loading program's phase, step and load parameters with their units (``name``, the
    phase's name, is a key of the program's own, in ``model_extra``); empty for a single state."""
    from app.io.select import parameter_unit
    length = units.get("length") if isinstance(units, dict) else units.length
    if load.u_x is not None:
        return f"CD moved by u_x = {load.u_x:.4g} {length}, u_y = {load.u_y:.4g} {length}"
    if load.parameters is not None:
        extra = load.model_extra or {}
        phase = extra["name"] if "name" in extra else "" if load.phase is None else load.phase
        step = "" if load.step is None else load.step
        return (f"phase '{phase}', step {step}: "
                + ", ".join(f"{k} = {v:.4g}{' ' + u if (u := parameter_unit(k, units)) else ''}"
                            for k, v in load.parameters.items()))
    return ""


def state_picture(fd: FieldData, state: StateResult, field: str, res, scale: float, path: pathlib.Path,
                  units: Units, scene: str) -> pathlib.Path:
    """Screenshot of the body at ``state``, coloured by ``field`` (``von_mises`` per cell, else the
    displacement magnitude), displacements drawn ``scale`` times, contact nodes marked by status;
    written to ``path`` as a PNG of ``res`` pixels, which is returned."""
    k = fd.state_index.index(state.index)
    u = fd.state_u[k]
    grid = fd.grid(scale * u)
    pl = plotter(res)
    if field == "von_mises":
        grid.cell_data["von Mises"] = fd.state_vm[k]
        name, bar = "von Mises", f"von Mises stress [{_unit(units.stress, 'MPa')}]"
    else:
        grid.point_data["u"] = np.linalg.norm(u, axis=1)
        name, bar = "u", f"displacement magnitude [{units.length}]"
    add_body(pl, fd, grid, scale * u, scalars=name, cmap="viridis", scalar_bar_args=bar_args(bar, "%.3g", res))
    pts = fd.points + scale * u
    groups: dict[str, list[int]] = {key: [] for key in ("stick", "slip", "free", "zero")}
    for nd, j in zip(state.nodes, fd.contact):
        groups[nd.status].append(int(j))
    legend = markers(pl, pts, groups, size=max(9.0, res[0] / 100))
    c = state.classification
    title = [f"{scene}: state {state.index}, {c.stick} stick / {c.slip} slip / {c.free} free"
             + (f" / {c.zero} zero" if c.zero else ""),
             _where(state.load, units) + ("" if scale == 1.0 else f"; displacements drawn x{scale:g}")]
    return finish(pl, fd, pts, title, legend, path, res)


def mode_picture(fd: FieldData, meta: dict, state: StateResult, res, path: pathlib.Path, scene: str,
                 units: Units | None = None, grow: float = 1.0, when: str | None = None,
                 statuses: list[int] | None = None) -> pathlib.Path:
    """Screenshot of the mode ``meta`` (an MCEIP solution at ``state``: its entry in fields.npz's
    ``modes_json``, with ``name``, ``state``, ``problem``, ``value`` and ``pattern``), drawn with
    its largest displacement as large as the mesh allows without folding (at most 12 % of the
    body's smaller side, app/plot/canvas.py), that scale stated, and coloured by magnitude; the slip
    nodes are marked by whether they slip or stay stuck in the mode. Written to ``path``, which is
    returned. ``grow``: a frame of :func:`mode_animation`, the mode at that fraction of its drawn
    amplitude (the view fixed by the full one), ``when`` its time in the title."""
    v = fd.mode(meta["name"])
    full = fd.mode_amplitude(v)                  # the largest displacement drawn (the mesh never folds)
    amp = full * grow
    grid = fd.grid(amp * v)
    grid.point_data["mode"] = np.linalg.norm(v, axis=1)
    pl = plotter(res)
    add_body(pl, fd, grid, amp * v, scalars="mode", cmap="plasma",
              scalar_bar_args=bar_args("mode displacement magnitude (max 1)", "%.2f", res))
    pts = fd.points + amp * v
    groups: dict[str, list[int]] = {key: [] for key in ("stick", "slip_mode", "stuck_mode", "free", "zero")}
    pattern = list(meta.get("pattern") or [])
    slip_k = 0
    stuck_nodes = []
    for pos, (nd, j) in enumerate(zip(state.nodes, fd.contact)):
        st = nd.status
        if st == "slip":
            in_mode = pattern[slip_k] if slip_k < len(pattern) else "slip"
            slip_k += 1
            groups["slip_mode" if in_mode == "slip" else "stuck_mode"].append(int(j))
            if in_mode != "slip":
                stuck_nodes.append(pos + 1)
        else:
            groups[st].append(int(j))
    if statuses is not None:      # a frame of the dynamics: the nodes as the simulation found them
        groups = {key: [int(j) for j, c in zip(fd.contact, statuses) if c == code]
                  for key, code in (("free", 0), ("stick", 1), ("slip", 2))}
    legend = markers(pl, pts, groups, size=max(9.0, res[0] / 100))
    c = state.classification
    what = PROBLEM_TITLE.get(meta["problem"], meta["problem"])
    if not truetype_font():      # VTK's own font has no Greek letters
        what = what.replace("\u03bc", "mu").replace("\u03bb\u00b2", "lambda^2")
    stuck = (f"{len(stuck_nodes)} of {c.slip} slip nodes stuck in the mode (node{'s' if len(stuck_nodes) > 1 else ''} "
             + ", ".join(str(k) for k in stuck_nodes) + " numbered along the obstacle)") if stuck_nodes else \
        f"all {c.slip} slip nodes slip in the mode"
    unit = "" if meta["problem"] == "mceip_mu" else " " + ("1/s^2" if units is None else units.lambda2)
    h = fd.element_size()
    length = units.length if units is not None else ""
    title = [f"{what} = {meta['value']:.6g}{unit}",
             f"{scene}: state {meta['state']}, {c.stick} stick / {c.slip} slip / {c.free} free; {stuck}",
             f"largest displacement drawn {full:.3g} {length} = {full / h:.2g} h (element size h = {h:.3g} {length})",
             *([when] if when else [])]
    return finish(pl, fd, pts, title, legend, path, res, extent=fd.points + full * v)


def mode_animation(fd: FieldData, meta: dict, state: StateResult, res, path: pathlib.Path, scene: str,
                   units: Units | None = None) -> pathlib.Path:
    """An animated GIF of the mode ``meta`` growing, as the divergence it predicts: ``u0 + a(t) v``
    with ``a(t) = a0 exp(lambda t)`` for a mode with ``lambda^2 > 0`` (MCEIP-lambda^2, the
    sufficient condition; the paper's eq. (8)), from 5 % of the drawn amplitude to all of it over
    ``t = ln(20) / lambda``, each frame titled with its time; linear growth for the static mode of
    MCEIP-mu (``lambda = 0``, the transition). Written to ``path``, which is returned."""
    from app.io.select import mode_growth
    lam2 = float(meta["value"]) if meta["problem"] != "mceip_mu" else 0.0
    lam = float(np.sqrt(lam2)) if lam2 > 0 else 0.0
    time_unit = "s" if units is None or not units.time else units.time

    def frame(item, png: pathlib.Path) -> pathlib.Path:
        t, grow = item
        when = (f"growing as a0 exp(lambda t), lambda = {lam:.4g} 1/{time_unit}: t = {1e3 * t:.3g} m{time_unit}"
                if t is not None else "static mode (lambda = 0): the amplitude drawn growing linearly")
        return mode_picture(fd, meta, state, res, png, scene, units, grow, when)
    return _animate(path, mode_growth(meta["problem"], meta["value"]), frame)


def _animate(path: pathlib.Path, items, draw) -> pathlib.Path:
    """An animated GIF at ``path``: one frame per item, drawn by ``draw(item, png_path)`` into a
    temporary PNG (255 colours each, 90 ms a frame, looping)."""
    import tempfile

    from PIL import Image
    frames = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, item in enumerate(items):
            with Image.open(draw(item, pathlib.Path(tmp) / f"{k:03d}.png")) as im:
                frames.append(im.convert("P", palette=Image.ADAPTIVE, colors=255))
    path.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:], duration=90, loop=0,
                   optimize=False)
    return path


def transient_animation(fd: FieldData, meta: dict, state: StateResult, record, res, path: pathlib.Path,
                        scene: str, units: Units | None = None) -> pathlib.Path:
    """An animated GIF of the simulated dynamics from ``state`` (a results.json ``transient``
    record whose divergence mode is ``meta``): the mode drawn at the amplitude the finest run
    reached at each of :data:`app.io.select.FRAMES` times (the last at the full drawn amplitude),
    the contact nodes coloured by the statuses the simulation found then, the time and the
    amplitude in the title."""
    from app.io.select import FRAMES
    run = record.runs[-1]
    t = np.asarray(run.series["t"], dtype=float)
    a = np.abs(np.asarray(run.series["amplitude"], dtype=float))
    stat = run.series.get("status") or []
    time_unit = "s" if units is None or not units.time else units.time
    picks = np.unique(np.linspace(0, len(t) - 1, FRAMES).astype(int))

    def frame(j, png: pathlib.Path) -> pathlib.Path:
        when = (f"the simulated motion at mu = {float(record.mu):g}: t = {1e3 * t[j]:.3g} m{time_unit}, "
                f"amplitude {a[j] / float(record.eps):.3g} x its start (drawn scaled)")
        return mode_picture(fd, meta, state, res, png, scene, units, float(a[j] / max(a[-1], 1e-300)), when,
                            statuses=stat[j] if j < len(stat) else None)
    return _animate(path, picks, frame)


def draw_screenshots(study: StudyResult, pictured: list[int], cfg: dict, outdir: pathlib.Path,
                     fields_path: pathlib.Path, progress=None) -> tuple[list[pathlib.Path], list[str]]:
    """Every screenshot the scene asks for (``cfg``: its ``outputs.screenshots``), of the states
    ``pictured``, drawn in this process into ``outdir``; returns (files, notes).

    Not in a process that has loaded DOLFINx (see the module docstring): there
    app/plot/pictures.py has them drawn by a child process (app/plot/worker.py, :func:`job_of`)."""
    if "dolfinx.cpp" in sys.modules:
        raise RuntimeError("screenshots cannot be drawn in a process that has loaded DOLFINx: "
                           "use app.plot.pictures.draw_outputs (it draws them in a child process)")
    return _draw(study, pictured, cfg, outdir, fields_path, progress)


def job_of(study: StudyResult, pictured: list[int], cfg: dict, outdir: pathlib.Path, fields_path: pathlib.Path,
           progress=None) -> dict:
    """The job of a drawing process, as JSON data: ``results`` is the study's results.json
    document (:meth:`StudyResult.to_json`, read back by :meth:`StudyResult.from_json`), with the other
    arguments of :func:`draw_screenshots`."""
    return {"results": study.to_json(), "pictured": list(pictured), "cfg": cfg, "outdir": str(outdir),
            "fields": str(fields_path), "progress": bool(progress is not None and getattr(progress, "enabled", False))}


def resolution_arg(cfg: dict) -> str:
    """The pictures' resolution as the drawing process's argument ``WxH``."""
    w, h = cfg.get("resolution") or (1200, 800)
    return f"{int(w)}x{int(h)}"


def _lambda2_mode(fd: FieldData, study: StudyResult, index: int, record) -> dict | None:
    """The fields.npz entry of the MCEIP-lambda^2 mode a transient record started from (the largest
    lambda^2 of the state's classification), None when the run saved none."""
    from app.io.select import analyses_of
    first = analyses_of(study.states, index)[1]
    cands = [m for m in fd.modes if m["state"] == first and m["problem"] == "mceip_lambda2"]
    if not cands or record.lambda2 is None:
        return None
    return min(cands, key=lambda m: abs(float(m["value"]) - float(record.lambda2)))


def _draw(study: StudyResult, pictured: list[int], cfg: dict, outdir: pathlib.Path,
          fields_path: pathlib.Path, progress=None) -> tuple[list[pathlib.Path], list[str]]:
    from app.io.select import analyses_of, mode_name, modes_of
    if not os.path.lexists(fields_path):
        return [], [f"screenshots left out: {fields_path} is missing (the fields are computed by the run)"]
    fd = read_fields(fields_path)
    res = tuple(cfg.get("resolution") or (1200, 800))
    field = cfg.get("field", "von_mises")
    scale = float(cfg.get("scale", 1.0))
    by_index = {s.index: s for s in study.states}
    files, notes = [], []
    jobs = []
    for i in pictured:
        if i not in fd.state_index:
            notes.append(f"screenshot of state {i} left out: its field is not in {fields_path.name}")
            continue
        jobs.append(("state", i, None))
        if cfg.get("modes", True):
            analyses, first = analyses_of(study.states, i)
            for problem, k, sol in modes_of(analyses):
                name = mode_name(first, problem, k, _value(sol.value))
                if name in [j[2] for j in jobs if j[0] == "mode"]:      # its animation is listed with it
                    continue
                jobs.append(("mode", i, name))
                if cfg.get("animate"):
                    jobs.append(("animation", i, name))
    known = {m["name"]: m for m in fd.modes}
    if cfg.get("animate"):         # the simulated dynamics, where the study ran them from a pictured state
        for record in study.transient or ():
            if record.runs and record.predicted_rate is not None and record.state in pictured:
                jobs.append(("transient", record.state, record))
    bar = progress.bar(len(jobs), "screenshots", unit="picture") if progress is not None else None
    try:
        for kind, i, name in jobs:
            if kind == "state":
                files.append(state_picture(fd, by_index[i], field, res, scale,
                                           outdir / f"state_{i:04d}_{field}.png", study.units, study.scene))
            elif kind == "transient":
                meta = _lambda2_mode(fd, study, i, name)
                if meta is None:
                    notes.append(f"animation of the dynamics from state {i} left out: its MCEIP-lambda^2 mode is "
                                 f"not in {fields_path.name}")
                else:
                    files.append(transient_animation(fd, meta, by_index[i], name, res,
                                                     outdir / f"transient_s{i:04d}.gif", study.scene, study.units))
            elif name in known and kind == "animation":
                meta = known[name]
                files.append(mode_animation(fd, meta, by_index[meta["state"]], res, outdir / f"mode_{name}.gif",
                                            study.scene, study.units))
            elif name in known:
                meta = known[name]
                files.append(mode_picture(fd, meta, by_index[meta["state"]], res, outdir / f"mode_{name}.png",
                                          study.scene, study.units))
            else:
                notes.append(f"screenshot of mode {name} left out: its field is not in {fields_path.name}")
            if bar is not None:
                bar.update(1)
    finally:
        close_plotters()
        if bar is not None:
            bar.close()
    return files, notes


def read_fields(path: pathlib.Path) -> FieldData:
    """The fields of ``path`` (a fields.npz of a results folder, not trusted): a regular file whose
    arrays, by their ``.npy`` headers, fit in memory (app/io/untrusted.py); raises
    :class:`app.io.untrusted.UntrustedFile` otherwise."""
    from app.io.untrusted import check_npz, memory_limit, opened
    with opened(path, int(min(memory_limit(), 2**62))) as f:
        check_npz(f, str(path))
        return FieldData(f)


def _value(v) -> float:
    return float(v)


def draw_job(job: dict) -> tuple[list[pathlib.Path], list[str]]:
    """Draw a job of :func:`job_of` (in the drawing process)."""
    import types
    progress = None
    if job["progress"]:
        from app.common.progress import Progress
        progress = Progress(enabled=True, comm=types.SimpleNamespace(rank=0))
    return _draw(StudyResult.from_json(job["results"]), job["pictured"], job["cfg"], pathlib.Path(job["outdir"]),
                 pathlib.Path(job["fields"]), progress)


def warm_up(size: str) -> None:
    """Import what the pictures use and render a small scene like theirs (mesh with scalars and
    edges, spheres, lines, text in the TrueType font, scalar bar) in the plotter of resolution
    ``size`` (``WxH``) that they will reuse: OpenGL context and shaders are then ready."""
    res = tuple(int(v) for v in size.split("x"))
    pv = import_pyvista()
    pl = plotter(res)
    grid = pv.UnstructuredGrid(np.array([3, 0, 1, 2]), np.array([pv.CellType.TRIANGLE], dtype=np.uint8),
                               np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    grid.point_data["s"] = np.arange(3.0)
    pl.add_mesh(grid, scalars="s", cmap="viridis", show_edges=True, edge_color="#303030", line_width=0.5,
                scalar_bar_args=bar_args("s", "%.3g", res))
    pl.add_points(np.array([[0.5, 0.0, 0.05]]), color="#1f77b4", point_size=10.0, render_points_as_spheres=True)
    pl.add_mesh(pv.Line((0.0, 0.0, 0.01), (1.0, 1.0, 0.01)), color="#666666", line_width=1.5)
    text(pl, "\u03bc warm-up", 0.01, 0.9, font_size(res))
    pl.suppress_rendering = False
    pl.screenshot(None, return_img=True)
