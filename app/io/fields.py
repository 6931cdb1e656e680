"""Fields of a meshed system for ParaView and the screenshots, computed while the system is alive.

Works through the system's field capability only (``system.fields``, an
:class:`app.systems.base.FieldSource`: the block, a Gmsh body), with no assumption on the body's
shape, the contact side or the obstacle. Per equilibrium state: the displacement (from the
contact reactions and the state's prescribed loading: displacements, tractions, body force; one
solve with the factorised K), the von Mises stress (cellwise, at the cell midpoint), and at the
contact nodes their status, the reactions and the impending slip direction, in global x/y from
each node's own tangent t and outward normal n (``r = r_T t + r_N n``, slip along ``-sign(r_T) t``).
Per divergence mode found (sufficient condition, MCEIP-mu, MCEIP-lambda^2) its displacement,
normalised to max |v| = 1 (a shape: the scale of an eigenvector is arbitrary); modes live in the
system's DOFs, i.e. in the node frames (T, N) at contact nodes, and are rotated back to x/y:

* when the analysis kept the full vector in the reduced space of (10) (the sufficient condition,
  MCEIP-lambda^2, MCEIP-mu with ``mceip_mu_method: full``) it is mapped back exactly:
  ``v_f = x_f``, ``v_Ts = -S sign_T x_Ts``, removed DOFs (stick nodes, slip normals) 0;
* the condensed MCEIP-mu keeps only ``x_Ts``: the mode is the static response with
  ``v_T = -S x_Ts`` and ``v_N = 0`` at slip nodes, ``v = 0`` at stick nodes and free nodes
  unconstrained, i.e. ``W_cc r_c = v_c`` on the constrained contact DOFs and
  ``v = K^-1 B^T r`` (exact for MCEIP-mu: its free rows are those of K).

Everything is gathered on rank 0 in a canonical node and cell order (sorted by coordinates), so
the files do not depend on the number of MPI ranks, and rank 0 writes:

* ``paraview/states.xdmf`` (+ ``states.h5``, and ``states.1.h5`` ... past 64 MiB of data): one mesh,
  time = the load (app/io/select.py ``load_axis``: the plots' x-axis), fields ``displacement``
  [length], ``von_mises`` [stress, cell data], ``contact_status`` (-1 not a contact node, 0 free,
  1 zero, 2 stick, 3 slip), ``reaction`` (nodal contact force on the body, global x/y) [force],
  ``slip_direction`` (unit vector of impending slip along the node's tangent, global x/y; 0 elsewhere);
* ``paraview/modes.vtu``: one point field per mode, named ``s<state>_<problem>_<k>_<value>``;
  with ``screenshots.animate``, ``paraview/mode_<name>.xdmf`` for each mode of a pictured state:
  the mode growing in time as the GIF shows it (:func:`_mode_series`);
* ``fields/fields.npz``: the mesh, the contact nodes and their frames, the obstacle line, the
  pictured states' fields and their modes, for the screenshots and ``python -m app render``.

A system without a mesh (matrices, two particles) has no fields: the stage then records
"not applicable" (the schema refuses ``outputs.paraview``/``screenshots`` written by the user).
"""
from __future__ import annotations

import json
import logging
import pathlib
from typing import Sequence

import numpy as np
from mpi4py import MPI

from app.io.gather import MeshGather
from app.io.result import MceipSolution, StateResult
from app.io.select import analyses_of, load_axis, mode_name, modes_of, select_states
from app.io.xdmf import XdmfSeries
from app.loading.classify import Classification
from app.systems import jit

log = logging.getLogger(__name__)

STATUS_CODE = {"free": 0, "zero": 1, "stick": 2, "slip": 3}


def wants_fields(scene) -> bool:
    """The scene's outputs need fields (ParaView files, screenshots); a system type without a mesh
    then gets a "not applicable" record from :func:`compute_fields`."""
    outputs = getattr(scene, "outputs", None)
    return outputs is not None and outputs.fields


def _classification(entry: StateResult) -> Classification:
    return Classification(tuple(n.status for n in entry.nodes), tuple(int(n.sign) for n in entry.nodes))


def _curved(entry: StateResult) -> dict | None:
    """What the loading path recorded of a curved obstacle's contact at this state (app/loading/curved.py)."""
    return (entry.model_extra or {}).get("curved_contact")


class _FieldMaker:
    """Fields of one meshed system through its :class:`app.systems.base.FieldSource` (collective methods)."""

    def __init__(self, system):
        import dolfinx.fem
        self.system = system
        self.src = src = system.fields
        self.comm = system.comm
        V = src.V
        self.scale = src.length_scale
        self.gather = MeshGather(V, self.scale)
        Q = dolfinx.fem.FunctionSpace(V.mesh, ("DG", 0), **jit.params())
        self.q = dolfinx.fem.Function(Q, name="von_mises")
        self.u = dolfinx.fem.Function(V, name="displacement")
        self.vm = dolfinx.fem.Expression(src.von_mises(self.u), Q.element.interpolation_points(), **jit.params())
        n_cells = V.mesh.topology.index_map(V.mesh.topology.dim).size_local
        self.q_dofs = Q.dofmap.list.array[:n_cells]
        self.n = len(system.nodes)
        self.dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes], dtype=np.int64).ravel()
        self.signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()

    def state(self, entry: StateResult) -> tuple[np.ndarray | None, np.ndarray | None, float]:
        """Displacement (N, 2) and von Mises (C,) of a state on rank 0, and the largest mismatch
        of the field's contact displacements with the state's (relative to the field's scale)."""
        nodes = entry.nodes
        load = entry.load.to_dict()          # the system type's loading record (FieldSource.response)
        r = np.ravel([[n.r_T, n.r_N] for n in nodes])
        cc = _curved(entry)
        if cc is not None:               # a curved obstacle: reactions in the contact frames -> node frames
            from app.analyses.pencils.curvature import frame_matrix
            r = frame_matrix(cc["frame"], len(nodes)) @ r
        vec = self.src.response(load, r)
        try:
            uc = self._contact_values(vec)
            f = self.src.to_function(vec, load)
        finally:
            vec.destroy()
        self.u.x.array[:] = f.x.array
        self.q.interpolate(self.vm)
        # a state's u_N is the normal displacement minus the initial gap (app/loading/program.py)
        want = (np.asarray(cc["u_system"], dtype=float) if cc is not None else          # app/loading/curved.py
                np.ravel([[n.u_T, n.u_N + g] for n, g in zip(nodes, self.src.gaps)]))
        big = self.comm.allreduce(float(np.max(np.abs(f.x.array), initial=0.0)), op=MPI.MAX)   # MPI collective
        mismatch = float(np.max(np.abs(uc - want), initial=0.0) / max(np.max(np.abs(want), initial=0.0), big, 1e-300))
        return self.gather.nodal(self.u.x.array), self.gather.cellwise(self.q.x.array[self.q_dofs]), mismatch

    def _contact_values(self, vec) -> np.ndarray:
        """Contact displacements of a system vector in paper axes (T0, N0, T1, ...), replicated."""
        from app.loading.flexibility import contact_entries
        return contact_entries(vec, self.dofs, self.signs)                 # MPI collective

    def _to_node_frames(self, arr: np.ndarray, r0: int, entry: StateResult, cls) -> None:
        """On a curved obstacle the pencils' slip-node DOFs are in the contact frames
        (app/analyses/pencils/curvature.py): rotate them back to the node frames, in place (owned DOFs)."""
        if _curved(entry) is None:
            return
        for node, f in zip(self.system.nodes, _slip_frames(entry, cls)):
            a, b, c, d = f
            iT, iN = node.dof_T - r0, node.dof_N - r0
            if (a, b, c, d) == (1.0, 0.0, 0.0, 1.0) or not (0 <= iT < len(arr) and 0 <= iN < len(arr)):
                continue
            vT, vN = arr[iT] * node.sign_T, arr[iN] * node.sign_N
            arr[iT], arr[iN] = node.sign_T * (a * vT + c * vN), node.sign_N * (b * vT + d * vN)

    def mode(self, entry: StateResult, problem: str, sol: MceipSolution) -> tuple[np.ndarray | None, str]:
        """Mode displacement (N, 2) on rank 0, normalised to max |v| = 1, and how it was built."""
        cls = _classification(entry)
        x = sol.x
        if x is not None:
            from app.analyses.pencils.reduced import reduced_space
            space = reduced_space(self.system, cls)
            kept = space.kept.getIndices()
            offset = self.comm.exscan(len(kept)) or 0                            # MPI collective
            vec = self.system.K.createVecRight()
            r0, _ = vec.getOwnershipRange()
            arr = np.zeros(vec.getLocalSize())
            arr[kept - r0] = space.d_local * np.asarray(x)[offset:offset + len(kept)]
            self._to_node_frames(arr, r0, entry, cls)
            vec.setArray(arr)
            space.destroy()
            how = "exact: kept-space vector mapped back (v_f = x_f, v_Ts = -S x_Ts, removed DOFs 0)"
        else:
            v_c = np.zeros(2 * self.n)
            # constrained: both DOFs of stick and slip nodes (v_N = 0 at slip nodes); free nodes are not
            con = [d for i, st in enumerate(cls.status) if st in ("stick", "slip") for d in (2 * i, 2 * i + 1)]
            slip = cls.slip
            xts = np.asarray(sol.x_Ts, dtype=float)
            v_c[2 * slip] = -cls.slip_signs * xts
            if _curved(entry) is not None:     # contact frames -> node frames (slip nodes)
                from app.analyses.pencils.curvature import frame_matrix
                v_c = frame_matrix(_slip_frames(entry, cls), self.n) @ v_c
            con = np.asarray(con, dtype=np.int64)
            r = np.zeros(2 * self.n)
            r[con] = np.linalg.solve(self.src.W[np.ix_(con, con)], v_c[con])
            vec = self.src.response(None, r)
            how = "static response to the contact rates (W_cc r_c = v_c): exact for MCEIP-mu"
        try:
            f = self.src.to_function(vec, None)
        finally:
            vec.destroy()
        v = self.gather.nodal(f.x.array)
        if v is not None:
            big = float(np.max(np.linalg.norm(v, axis=1)))
            v = v / big if big > 0 else v
        return v, how


def _pad3(v: np.ndarray) -> np.ndarray:
    return np.column_stack([v, np.zeros(len(v))])


def compute_fields(scene, system, out_states: Sequence[StateResult], stages, progress,
                   outdir: pathlib.Path | None) -> dict:
    """The field stage of a study (MPI collective); writes the files on rank 0; returns the record
    of what it did (identical on every rank) for results.json ``outputs``."""
    if system.fields is None:
        why = f"ParaView files and screenshots not applicable: a {scene.system.type} system has no mesh"
        log.info("fields: %s", why)
        return {"notes": [why], "files": [], "fields_not_applicable": why}
    if outdir is None:
        return {"notes": ["fields not computed: the study was run without an output folder"], "files": []}
    return _compute_fields(scene, system, out_states, stages, progress, outdir)


def _compute_fields(scene, system, out_states: Sequence[StateResult], stages, progress, outdir: pathlib.Path) -> dict:
    """The body of :func:`compute_fields` for a meshed system and an output folder."""
    outputs = scene.outputs
    comm = system.comm
    record: dict = {"notes": [], "files": []}
    pictured, notes = select_states(out_states, outputs.states)
    record["pictured_states"] = pictured
    record["notes"] += notes
    shots = outputs.screenshots
    with stages("fields (ParaView files, screenshot data)"):
        maker = _FieldMaker(system)
        src = system.fields
        g = maker.gather
        by_index = {s.index: s for s in out_states}
        state_ids = [s.index for s in out_states] if outputs.paraview else list(pictured)
        # modes: of every distinct classification for ParaView, of the pictured states for screenshots
        mode_firsts = set()
        if outputs.paraview:
            mode_firsts |= {s.index for s in out_states if s.analyses_shared_with is None}
        if shots is not None and shots.modes:
            mode_firsts |= {analyses_of(out_states, i)[1] for i in pictured}
        rank0 = comm.rank == 0
        paraview_dir = outdir / "paraview"
        contact = None
        if rank0:
            contact = g.contact_points(src.contact_xy, maker.scale)
            if outputs.paraview:
                paraview_dir.mkdir(parents=True, exist_ok=True)
        series = XdmfSeries(paraview_dir / "states.xdmf") if (rank0 and outputs.paraview) else None
        # ParaView's time: the load (CD's travel, a program's parameters) where there is one, else the index
        at = dict(zip((s.index for s in out_states), load_axis(out_states, system.units)[0]))
        kept_u, kept_vm, worst = _state_fields(maker, [by_index[i] for i in state_ids], pictured, contact,
                                               series, progress, at)
        record["contact_displacement_check"] = worst
        log.info("fields: %d state(s) computed (contact displacements reproduced to %.2g relative)",
                 len(state_ids), worst)
        if worst > 1e-6:
            log.warning("fields: the displacement fields differ from the states' contact displacements by %.3g "
                        "(relative)", worst)
        modes, meta = _mode_fields(maker, [by_index[first] for first in sorted(mode_firsts)])
        record["modes"] = [{"name": m["name"], "built": m["built"]} for m in meta] if rank0 else []
        if rank0:
            if outputs.paraview:
                import meshio
                paraview_dir.mkdir(parents=True, exist_ok=True)
                meshio.write(paraview_dir / "modes.vtu",
                             meshio.Mesh(_pad3(g.points), [(g.cell_type, g.cells)],
                                         point_data={n: _pad3(v) for n, v in modes.items()}))
                record["files"] += (["paraview/states.xdmf"] + [f"paraview/{p.name}" for p in series.parts]
                                    + ["paraview/modes.vtu"])
                if shots is not None and shots.animate:
                    record["files"] += _mode_series(paraview_dir, g, modes, meta, pictured, out_states, kept_u)
            if shots is not None:
                _write_screenshot_data(outdir / "fields", maker, contact, kept_u, kept_vm, modes, meta)
                record["files"].append("fields/fields.npz")
            log.info("fields: %d mode(s); wrote %s", len(meta), ", ".join(record["files"]) or "nothing")
    record = comm.bcast(record, root=0)                                          # MPI collective
    return record


def _state_fields(maker: "_FieldMaker", entries: list[StateResult], pictured, contact, series: XdmfSeries | None,
                  progress, at: dict) -> tuple[dict, dict, float]:
    """The fields of the states ``entries`` (MPI collective): on rank 0 written to the ParaView
    ``series`` (if any) and kept for the ``pictured`` states. Returns the kept displacements and
    von Mises stresses by state index and the largest contact-displacement mismatch."""
    g, src, rank0 = maker.gather, maker.src, maker.comm.rank == 0
    writer = series.__enter__() if series is not None else None
    if writer is not None:
        writer.write_points_cells(g.points, [(g.cell_type, g.cells)])
    kept_u, kept_vm = {}, {}
    worst = 0.0
    bar = progress.bar(len(entries), "fields")
    try:
        for entry in entries:
            idx = entry.index
            u, vm, mismatch = maker.state(entry)
            worst = max(worst, mismatch)
            if rank0:
                if writer is not None:
                    writer.write_data(float(at[idx]), point_data=_contact_fields(entry, u, contact, src),
                                      cell_data={"von_mises": [vm]})
                if idx in pictured:
                    kept_u[idx], kept_vm[idx] = u, vm
            bar.update(1)
    except BaseException as err:
        bar.close()
        if series is not None:
            series.__exit__(type(err), err, err.__traceback__)
        raise
    bar.close()
    if series is not None:
        series.__exit__(None, None, None)
    return kept_u, kept_vm, worst


def _mode_series(paraview_dir: pathlib.Path, g, modes: dict, meta: list[dict], pictured: list[int],
                 out_states: Sequence[StateResult], kept_u: dict) -> list[str]:
    """``paraview/mode_<name>.xdmf`` for each mode of a pictured state (those the screenshots
    animate): the mode growing as the divergence it predicts, the frames of the GIF
    (:func:`app.io.select.mode_growth`), time = ``t`` in the time unit where ``lambda^2 > 0`` and
    the amplitude's fraction for MCEIP-mu's static mode; point fields ``state_displacement`` (the
    state's, constant) and ``mode`` (``a(t) v``, largest 1 at the last frame): warp by
    ``state_displacement + scale * mode`` (rank 0). Returns the files, relative to the folder."""
    from app.io.select import mode_growth
    files = []
    for i in pictured:
        first = analyses_of(out_states, i)[1]
        u0 = _pad3(kept_u[i])
        for m in (m for m in meta if m["state"] == first):
            v = _pad3(modes[m["name"]])
            series = XdmfSeries(paraview_dir / f"mode_{m['name']}.xdmf")
            writer = series.__enter__()
            try:
                writer.write_points_cells(g.points, [(g.cell_type, g.cells)])
                for t, a in mode_growth(m["problem"], m["value"]):
                    writer.write_data(float(a if t is None else t), point_data={"state_displacement": u0,
                                                                                "mode": a * v})
            except BaseException as err:
                series.__exit__(type(err), err, err.__traceback__)
                raise
            series.__exit__(None, None, None)
            files += [f"paraview/mode_{m['name']}.xdmf"] + [f"paraview/{p.name}" for p in series.parts]
    return files


def _mode_fields(maker: "_FieldMaker", entries: list[StateResult]) -> tuple[dict, list[dict]]:
    """The modes of the states ``entries`` (MPI collective): their displacements by name and
    their descriptions (both on rank 0 only)."""
    modes, meta = {}, []
    for entry in entries:
        first = entry.index
        for problem, k, sol in modes_of(entry.analyses):
            name = mode_name(first, problem, k, sol.value)
            v, how = maker.mode(entry, problem, sol)
            if maker.comm.rank == 0:
                modes[name] = v
                meta.append({"name": name, "state": first, "problem": problem, "k": k,
                             "value": float(sol.value), "pattern": list(sol.pattern),
                             "x_Ts": [float(v) for v in sol.x_Ts], "built": how})
    return modes, meta


def _write_screenshot_data(fdir: pathlib.Path, maker: "_FieldMaker", contact, kept_u: dict, kept_vm: dict,
                           modes: dict, meta: list[dict]) -> None:
    """``fields/fields.npz``: what the screenshots and ``python -m app render`` draw (rank 0)."""
    g, src = maker.gather, maker.src
    fdir.mkdir(parents=True, exist_ok=True)
    ids = sorted(kept_u)
    names = [m["name"] for m in meta]
    np.savez_compressed(
        fdir / "fields.npz", points=g.points, cells=g.cells, cell_type=np.array(g.cell_type),
        contact_points=contact, state_index=np.array(ids, dtype=np.int64),
        state_u=np.array([kept_u[i] for i in ids]).reshape(len(ids), len(g.points), 2),
        state_von_mises=np.array([kept_vm[i] for i in ids]).reshape(len(ids), len(g.cells)),
        mode_v=np.array([modes[n] for n in names]).reshape(len(names), len(g.points), 2),
        modes_json=np.array(json.dumps(meta)),
        contact_tangent=src.tangent, contact_normal=src.normal, length_scale=np.array(maker.scale),
        **({"obstacle_point": np.array(src.obstacle["point"], dtype=float),
            "obstacle_normal": np.array(src.obstacle["normal"], dtype=float)}
           if src.obstacle and "point" in src.obstacle else {}),
        **({"obstacle_circle": np.array([*src.obstacle["centre"], src.obstacle["radius"],
                                         1.0 if src.obstacle["side"] == "outside" else -1.0])}
           if src.obstacle and "centre" in src.obstacle else {}),
        **({"obstacle_polyline": np.array(src.obstacle["polyline"], dtype=float)}
           if src.obstacle and "polyline" in src.obstacle else {}))


def _slip_frames(entry: StateResult, cls) -> list:
    """The contact frames the pencils of a curved-obstacle state use: the state's at its slip
    nodes, the node's own elsewhere (app/analyses/pencils/curvature.py)."""
    frames = _curved(entry)["frame"]
    return [tuple(frames[i]) if st == "slip" else (1.0, 0.0, 0.0, 1.0) for i, st in enumerate(cls.status)]


def _contact_fields(entry: StateResult, u: np.ndarray, contact: np.ndarray, src) -> dict:
    """Point fields of one state: displacement and, at the contact nodes, status, reaction and slip
    direction in global x/y from each node's own frame (u = t u_T + n u_N)."""
    n_pts = len(u)
    status = np.full(n_pts, -1, dtype=np.int32)
    reaction = np.zeros((n_pts, 3))
    slip_dir = np.zeros((n_pts, 3))
    frames = (_curved(entry) or {}).get("frame") or [(1.0, 0.0, 0.0, 1.0)] * len(entry.nodes)
    for node, j, t0, n0, (a, b, c, d) in zip(entry.nodes, contact, src.tangent, src.normal, frames):
        t, n = a * t0 + b * n0, c * t0 + d * n0       # the contact frame (the node's own on a line)
        status[j] = STATUS_CODE[node.status]
        reaction[j, :2] = node.r_T * t + node.r_N * n
        if node.status == "slip":
            slip_dir[j, :2] = -float(node.sign) * t      # impending slip opposes r_T
    return {"displacement": _pad3(u), "contact_status": status, "reaction": reaction, "slip_direction": slip_dir}
