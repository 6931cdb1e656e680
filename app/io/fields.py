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

* ``paraview/states.xdmf`` (+ ``states.h5``, and ``states.1.h5`` ... past 64 MiB of data): one mesh, time = state index, fields ``displacement``
  [length], ``von_mises`` [stress, cell data], ``contact_status`` (-1 not a contact node, 0 free,
  1 zero, 2 stick, 3 slip), ``reaction`` (nodal contact force on the body, global x/y) [force],
  ``slip_direction`` (unit vector of impending slip along the node's tangent, global x/y; 0 elsewhere);
* ``paraview/modes.vtu``: one point field per mode, named ``s<state>_<problem>_<k>_<value>``;
* ``fields/fields.npz``: the mesh, the contact nodes and their frames, the obstacle line, the
  pictured states' fields and their modes, for the screenshots and ``python -m app render``.

A system without a mesh (matrices, two particles) has no fields: the stage then records
"not applicable" (the schema refuses ``outputs.paraview``/``screenshots`` written by the user).
"""
from __future__ import annotations

import json
import logging
import pathlib

import numpy as np
from mpi4py import MPI

from app.io.select import analyses_of, mode_name, modes_of, select_states
from app.loading.classify import Classification

log = logging.getLogger(__name__)

STATUS_CODE = {"free": 0, "zero": 1, "stick": 2, "slip": 3}


def wants_fields(scene) -> bool:
    """The scene's outputs need fields (ParaView files, screenshots); a system type without a mesh
    then gets a "not applicable" record from :func:`compute_fields`."""
    outputs = getattr(scene, "outputs", None)
    return outputs is not None and outputs.fields


class MeshGather:
    """Nodes and cells of the displacement space on rank 0, in a canonical (rank-independent) order."""

    def __init__(self, V, length_scale: float):
        import dolfinx.cpp
        mesh = V.mesh
        self.comm = mesh.comm
        im = V.dofmap.index_map
        self.n_own = im.size_local
        self.gidx = np.arange(im.local_range[0], im.local_range[1], dtype=np.int64)
        x = V.tabulate_dof_coordinates()[:self.n_own, :2]
        tdim = mesh.topology.dim
        self.n_cells = mesh.topology.index_map(tdim).size_local
        ndofs = V.dofmap.dof_layout.num_dofs
        perm = np.argsort(dolfinx.cpp.io.perm_vtk(mesh.topology.cell_type, ndofs))   # DOLFINx -> VTK order
        local = V.dofmap.list.array.reshape(-1, ndofs)[:self.n_cells][:, perm]
        cells = im.local_to_global(local.ravel().astype(np.int32)).reshape(local.shape)
        parts = self.comm.gather((self.gidx, x, cells), root=0)              # MPI collective
        self.points = self.cells = self.point_order = self.cell_order = None
        self.cell_type = "triangle" if ndofs == 3 else "triangle6"
        if self.comm.rank == 0:
            g = np.concatenate([p[0] for p in parts])
            xs = np.concatenate([p[1] for p in parts])
            n = len(g)
            pts = np.empty((n, 2))
            pts[g] = xs
            key = np.round(pts / length_scale, 9)
            order = np.lexsort((key[:, 0], key[:, 1]))            # by y, then x
            new_of_global = np.empty(n, dtype=np.int64)
            new_of_global[order] = np.arange(n)
            self.points = pts[order]
            cells = new_of_global[np.concatenate([p[2] for p in parts])]
            # each cell starts at its smallest vertex (a cyclic rotation: orientation and the VTK
            # order of the mid-side nodes kept), whatever the mesh generator's local order
            rot = (np.argmin(cells[:, :3], axis=1)[:, None] + np.arange(3)) % 3
            cells = np.hstack([np.take_along_axis(cells[:, 3 * b:3 * b + 3], rot, axis=1)
                               for b in range(cells.shape[1] // 3)])
            ckey = np.sort(cells, axis=1)
            self.cell_order = np.lexsort(ckey.T[::-1])
            self.cells = cells[self.cell_order]
            self.new_of_global = new_of_global

    def nodal(self, values: np.ndarray) -> np.ndarray | None:
        """(N, 2) nodal vector on rank 0 from a blocked Function array (local, with ghosts)."""
        own = np.asarray(values)[:2 * self.n_own].reshape(-1, 2)
        parts = self.comm.gather((self.gidx, own), root=0)                 # MPI collective
        if self.comm.rank != 0:
            return None
        out = np.empty((len(self.points), 2))
        for g, v in parts:
            out[self.new_of_global[g]] = v
        return out

    def cellwise(self, values: np.ndarray) -> np.ndarray | None:
        """(C,) cell values on rank 0 from this rank's owned-cell values (in local cell order)."""
        parts = self.comm.gather(np.asarray(values)[:self.n_cells], root=0)   # MPI collective
        if self.comm.rank != 0:
            return None
        return np.concatenate(parts)[self.cell_order]

    def contact_points(self, xy: np.ndarray, length_scale: float) -> np.ndarray:
        """Indices (rank 0) of the mesh nodes at the contact nodes' coordinates ``xy`` (n, 2)."""
        from scipy.spatial import cKDTree
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        dist, idx = cKDTree(self.points).query(xy)
        if len(xy) and dist.max() > 1e-9 * length_scale:
            k = int(np.argmax(dist))
            raise RuntimeError(f"no mesh node at contact position ({xy[k, 0]}, {xy[k, 1]})")
        return np.asarray(idx, dtype=np.int64)


def _classification(entry: dict) -> Classification:
    return Classification(tuple(n["status"] for n in entry["nodes"]), tuple(int(n["sign"]) for n in entry["nodes"]))


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
        Q = dolfinx.fem.FunctionSpace(V.mesh, ("DG", 0))
        self.q = dolfinx.fem.Function(Q, name="von_mises")
        self.u = dolfinx.fem.Function(V, name="displacement")
        self.vm = dolfinx.fem.Expression(src.von_mises(self.u), Q.element.interpolation_points())
        n_cells = V.mesh.topology.index_map(V.mesh.topology.dim).size_local
        self.q_dofs = Q.dofmap.list.array[:n_cells]
        self.n = len(system.nodes)
        self.dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes], dtype=np.int64).ravel()
        self.signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()

    def state(self, entry: dict) -> tuple[np.ndarray | None, np.ndarray | None, float]:
        """Displacement (N, 2) and von Mises (C,) of a state on rank 0, and the largest mismatch
        of the field's contact displacements with the state's (relative to the field's scale)."""
        nodes = entry["nodes"]
        load = entry.get("load") or {}
        r = np.ravel([[n["r_T"], n["r_N"]] for n in nodes])
        cc = entry.get("curved_contact")
        if cc is not None:               # a curved obstacle: reactions in the contact frames -> node frames
            from app.analyses.curvature import frame_matrix
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
                np.ravel([[n["u_T"], n["u_N"] + g] for n, g in zip(nodes, self.src.gaps)]))
        big = self.comm.allreduce(float(np.max(np.abs(f.x.array), initial=0.0)), op=MPI.MAX)   # MPI collective
        mismatch = float(np.max(np.abs(uc - want), initial=0.0) / max(np.max(np.abs(want), initial=0.0), big, 1e-300))
        return self.gather.nodal(self.u.x.array), self.gather.cellwise(self.q.x.array[self.q_dofs]), mismatch

    def _contact_values(self, vec) -> np.ndarray:
        """Contact displacements of a system vector in paper axes (T0, N0, T1, ...), replicated."""
        from app.loading.flexibility import contact_entries
        return contact_entries(vec, self.dofs, self.signs)                 # MPI collective

    def _to_node_frames(self, arr: np.ndarray, r0: int, entry: dict, cls) -> None:
        """On a curved obstacle the pencils' slip-node DOFs are in the contact frames
        (app/analyses/curvature.py): rotate them back to the node frames, in place (owned DOFs)."""
        if entry.get("curved_contact") is None:
            return
        for node, f in zip(self.system.nodes, _slip_frames(entry, cls)):
            a, b, c, d = f
            iT, iN = node.dof_T - r0, node.dof_N - r0
            if (a, b, c, d) == (1.0, 0.0, 0.0, 1.0) or not (0 <= iT < len(arr) and 0 <= iN < len(arr)):
                continue
            vT, vN = arr[iT] * node.sign_T, arr[iN] * node.sign_N
            arr[iT], arr[iN] = node.sign_T * (a * vT + c * vN), node.sign_N * (b * vT + d * vN)

    def mode(self, entry: dict, problem: str, sol: dict) -> tuple[np.ndarray | None, str]:
        """Mode displacement (N, 2) on rank 0, normalised to max |v| = 1, and how it was built."""
        cls = _classification(entry)
        x = sol.get("_x")
        if x is not None:
            from app.analyses.pencils import reduced_space
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
            xts = np.asarray(sol["x_Ts"], dtype=float)
            v_c[2 * slip] = -cls.slip_signs * xts
            if entry.get("curved_contact") is not None:     # contact frames -> node frames (slip nodes)
                from app.analyses.curvature import frame_matrix
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


class _XdmfSeries:
    """meshio's XDMF time series whose HDF5 data are built in memory and written to disk by Python.

    HDF5 does not survive a full disk: after a failed write its object destructors raise inside
    h5py and the process then dies of a segmentation fault (HDF5 1.10, h5py 3.7), so a user would
    see a crash instead of "no space left". Here HDF5 only ever writes into a ``BytesIO``; each
    finished image goes to disk through ``open``/``write``, where a full disk is a plain
    ``OSError(ENOSPC)``. Memory stays bounded: a new ``.h5`` part is started once a part holds
    ``part_bytes`` of data (``states.h5`` holds the mesh and the first states, ``states.1.h5`` ...
    the next; the ``.xdmf`` names the part of each array). Parts are written with ``"xb"``: the
    series never overwrites a file (the folder is the study's own staging folder).
    """

    def __init__(self, path: pathlib.Path, part_bytes: int = 64 * 2**20):
        import h5py
        import meshio

        series = self

        class Writer(meshio.xdmf.TimeSeriesWriter):
            def __enter__(self):
                series._open_part()
                return self

            def __exit__(self, *exc):
                if exc and exc[0] is not None:      # the study failed: nothing more is written
                    series._discard_part()
                    return False
                series._close_part()
                import xml.etree.ElementTree as ET
                with open(self.filename, "xb") as f:
                    ET.ElementTree(self.xdmf_file).write(f)
                return False

            def write_data(self, t, point_data=None, cell_data=None):
                super().write_data(t, point_data=point_data, cell_data=cell_data)
                if series._held >= series.part_bytes:
                    series._close_part()
                    series._open_part()

            def numpy_to_xml_string(self, data):
                series._held += np.asarray(data).nbytes
                return super().numpy_to_xml_string(data)

        self._h5py = h5py
        self.path = pathlib.Path(path)
        self.part_bytes = int(part_bytes)
        self.parts: list[pathlib.Path] = []
        self._buf = None
        self._held = 0
        self.writer = Writer(self.path)

    def _open_part(self) -> None:
        import io
        k = len(self.parts)
        name = self.path.with_suffix(".h5") if k == 0 else self.path.with_suffix(f".{k}.h5")
        self.parts.append(name)
        self._buf = io.BytesIO()
        self.writer.h5_filename = str(name)
        self.writer.h5_file = self._h5py.File(self._buf, "w")
        self._held = 0

    def _close_part(self) -> None:
        self.writer.h5_file.close()
        image = self._buf.getvalue()
        self._buf = None
        with open(self.parts[-1], "xb") as f:
            f.write(image)

    def _discard_part(self) -> None:
        if self._buf is not None:
            self.writer.h5_file.close()
            self._buf = None

    def __enter__(self):
        return self.writer.__enter__()

    def __exit__(self, *exc):
        return self.writer.__exit__(*exc)


def _pad3(v: np.ndarray) -> np.ndarray:
    return np.column_stack([v, np.zeros(len(v))])


def compute_fields(scene, system, out_states: list[dict], stages, progress, outdir: pathlib.Path | None) -> dict:
    """The field stage of a study (MPI collective); writes the files on rank 0; returns the record
    of what it did (identical on every rank) for results.json ``outputs``."""
    try:
        if system.fields is None:
            why = f"ParaView files and screenshots not applicable: a {scene.system.type} system has no mesh"
            log.info("fields: %s", why)
            return {"notes": [why], "files": [], "fields_not_applicable": why}
        if outdir is None:
            return {"notes": ["fields not computed: the study was run without an output folder"], "files": []}
        return _compute_fields(scene, system, out_states, stages, progress, outdir)
    finally:
        # the in-memory mode vectors are not results
        for entry in out_states:
            for _, _, sol in modes_of(entry.get("analyses") or {}):
                sol.pop("_x", None)


def _compute_fields(scene, system, out_states: list[dict], stages, progress, outdir: pathlib.Path) -> dict:
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
        by_index = {s["index"]: s for s in out_states}
        state_ids = [s["index"] for s in out_states] if outputs.paraview else list(pictured)
        # modes: of every distinct classification for ParaView, of the pictured states for screenshots
        mode_firsts = set()
        if outputs.paraview:
            mode_firsts |= {s["index"] for s in out_states if s.get("analyses_shared_with") is None}
        if shots is not None and shots.modes:
            mode_firsts |= {analyses_of(out_states, i)[1] for i in pictured}
        rank0 = comm.rank == 0
        paraview_dir = outdir / "paraview"
        contact = None
        if rank0:
            contact = g.contact_points(src.contact_xy, maker.scale)
            if outputs.paraview:
                paraview_dir.mkdir(parents=True, exist_ok=True)
        series = _XdmfSeries(paraview_dir / "states.xdmf") if (rank0 and outputs.paraview) else None
        writer = series.__enter__() if series is not None else None
        if writer is not None:
            writer.write_points_cells(g.points, [(g.cell_type, g.cells)])
        kept_u, kept_vm = {}, {}
        worst = 0.0
        bar = progress.bar(len(state_ids), "fields")
        try:
            for idx in state_ids:
                entry = by_index[idx]
                u, vm, mismatch = maker.state(entry)
                worst = max(worst, mismatch)
                if rank0:
                    if writer is not None:
                        writer.write_data(idx, point_data=_contact_fields(entry, u, contact, src),
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
        record["contact_displacement_check"] = worst
        log.info("fields: %d state(s) computed (contact displacements reproduced to %.2g relative)",
                 len(state_ids), worst)
        if worst > 1e-6:
            log.warning("fields: the displacement fields differ from the states' contact displacements by %.3g "
                        "(relative)", worst)
        # modes
        modes, meta = {}, []
        for first in sorted(mode_firsts):
            entry = by_index[first]
            for problem, k, sol in modes_of(entry.get("analyses") or {}):
                name = mode_name(first, problem, k, sol["value"])
                v, how = maker.mode(entry, problem, sol)
                if rank0:
                    modes[name] = v
                    meta.append({"name": name, "state": first, "problem": problem, "k": k,
                                 "value": float(sol["value"]), "pattern": sol.get("pattern", []),
                                 "x_Ts": sol.get("x_Ts", []), "built": how})
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
            if shots is not None:
                fdir = outdir / "fields"
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
                       if src.obstacle and "centre" in src.obstacle else {}))
                record["files"].append("fields/fields.npz")
            log.info("fields: %d mode(s); wrote %s", len(meta), ", ".join(record["files"]) or "nothing")
    record = comm.bcast(record, root=0)                                          # MPI collective
    return record


def _slip_frames(entry: dict, cls) -> list:
    """The contact frames the pencils of a curved-obstacle state use: the state's at its slip
    nodes, the node's own elsewhere (app/analyses/curvature.py)."""
    frames = entry["curved_contact"]["frame"]
    return [tuple(frames[i]) if st == "slip" else (1.0, 0.0, 0.0, 1.0) for i, st in enumerate(cls.status)]


def _contact_fields(entry: dict, u: np.ndarray, contact: np.ndarray, src) -> dict:
    """Point fields of one state: displacement and, at the contact nodes, status, reaction and slip
    direction in global x/y from each node's own frame (u = t u_T + n u_N)."""
    n_pts = len(u)
    status = np.full(n_pts, -1, dtype=np.int32)
    reaction = np.zeros((n_pts, 3))
    slip_dir = np.zeros((n_pts, 3))
    frames = (entry.get("curved_contact") or {}).get("frame") or [(1.0, 0.0, 0.0, 1.0)] * len(entry["nodes"])
    for node, j, t0, n0, (a, b, c, d) in zip(entry["nodes"], contact, src.tangent, src.normal, frames):
        t, n = a * t0 + b * n0, c * t0 + d * n0       # the contact frame (the node's own on a line)
        status[j] = STATUS_CODE[node["status"]]
        reaction[j, :2] = node["r_T"] * t + node["r_N"] * n
        if node["status"] == "slip":
            slip_dir[j, :2] = -float(node["sign"]) * t      # impending slip opposes r_T
    return {"displacement": _pad3(u), "contact_status": status, "reaction": reaction, "slip_direction": slip_dir}
