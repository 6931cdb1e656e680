"""The child process that reads a user's Gmsh file (run by app/systems/gmsh/sandbox.py).

Run as a script, ``python -I child.py FILE OUTDIR MAX_NODES MAX_ELEMENTS MAX_DOFS``, inside the
sandbox (no write access outside OUTDIR, limits on time and memory): it imports only gmsh and
numpy, opens FILE (meshing a ``.geo`` in 2D), checks the model and writes into OUTDIR

* ``info.json``: the physical groups and sizes (or ``{"error": "..."}`` for a bad model),
* ``arrays.npz``: the arrays :func:`dolfinx.io.gmshio.model_to_mesh` would extract
  (app/systems/mesh_arrays.py), in the same order, and the samples of the free physical curves
  (``curve_*``, app/systems/gmsh/child_curves.py: possible rigid obstacles, sampled and then
  taken out of a ``.geo`` model before it is meshed, so none of their elements is the body's).

Checks (each a one-line error): the mesh is 2D (z = 0) with linear triangles only (no
quadrangles: mixed meshes are not supported by ``model_to_mesh``); every meshed surface belongs
to exactly one physical surface (elements outside physical groups would be silently dropped);
every curve to at most one physical curve; triangles have positive area and one orientation (a
mix of orientations or a zero area means inverted or degenerate elements); at most MAX_NODES
nodes and MAX_ELEMENTS triangles (a .geo's curves are meshed first and counted before its
surfaces are). It also counts, per physical curve, the line elements that are not on the body's
boundary (the contact curve must lie on it).
"""
from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

GMSH_LINE, GMSH_TRIANGLE = 1, 2
EXIT_MODEL_ERROR = 3           # info.json holds the message


class ModelError(Exception):
    """A user's model the app cannot use: ``str(err)`` is the one-line reason."""


def _short(err: Exception) -> str:
    return " ".join(str(err).split())[:160] or type(err).__name__


def _body_size(gmsh) -> float:
    """The extent of the points bounding the model's surfaces (of all its points without any)."""
    surfaces = gmsh.model.getEntities(2)
    pts = ([t for d, t in gmsh.model.getBoundary(surfaces, combined=False, oriented=False, recursive=True) if d == 0]
           if surfaces else [t for _, t in gmsh.model.getEntities(0)])
    xy = np.array([gmsh.model.getValue(0, t, [])[:2] for t in pts], dtype=float).reshape(-1, 2)
    ext = float(np.max(np.ptp(xy, axis=0))) if len(xy) else 0.0
    return ext if np.isfinite(ext) and ext > 0 else 1.0


def open_model(gmsh, path: pathlib.Path, max_nodes: int, max_elements: int, max_dofs: int,
               size_factor: float = 1.0) -> tuple[dict, dict]:
    """Load ``path`` into a new gmsh model, sample and remove its free physical curves, mesh a
    ``.geo`` in 2D within the limits, its characteristic lengths times ``size_factor`` (Gmsh's
    ``Mesh.CharacteristicLengthFactor``, times the file's own); renumber
    nodes and elements 1..N (model_to_mesh needs it).
    Returns the curves' ``(info, arrays)`` (app/systems/gmsh/child_curves.py)."""
    from child_curves import remove_curves, sample_curves
    gmsh.model.add("user")
    try:
        gmsh.open(str(path))
    except Exception as err:        # noqa: BLE001 - the user's file
        raise ModelError(f"gmsh cannot open {path.name}: {_short(err)}") from None
    is_geo = path.suffix.lower() == ".geo"
    curves = sample_curves(gmsh, _body_size(gmsh), is_geo)
    if is_geo:
        remove_curves(gmsh, {k: v["entities"] for k, v in curves[0][0].items()})
    if is_geo:
        if size_factor != 1.0:     # on top of the file's own factor, if it sets one
            factor = gmsh.option.getNumber("Mesh.CharacteristicLengthFactor")
            gmsh.option.setNumber("Mesh.CharacteristicLengthFactor", factor * size_factor)
        types, _, _ = gmsh.model.mesh.getElements(2)
        if len(types) == 0:
            try:
                gmsh.model.mesh.generate(1)
                n_curve_nodes = len(gmsh.model.mesh.getNodes()[0])
                if n_curve_nodes > max_nodes:
                    raise ModelError(f"meshing {path.name}: its curves alone have {n_curve_nodes} nodes (2 DOFs each), "
                                     f"more DOFs than settings.limits.max_dofs = {max_dofs}; use a coarser mesh or "
                                     "raise the limit")
                gmsh.model.mesh.generate(2)
            except ModelError:
                raise
            except Exception as err:    # noqa: BLE001
                raise ModelError(f"gmsh cannot mesh {path.name}: {_short(err)}") from None
    n_nodes = len(gmsh.model.mesh.getNodes()[0])
    n_tri = sum(len(t) for t in gmsh.model.mesh.getElements(2)[1])
    if n_nodes > max_nodes or n_tri > max_elements:
        raise ModelError(f"the mesh of {path.name} has {n_nodes} nodes ({2 * n_nodes} DOFs) and {n_tri} triangles, "
                         f"above the {max_nodes} nodes / {max_elements} triangles that settings.limits.max_dofs = "
                         f"{max_dofs} allows; use a coarser mesh or raise the limit")
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()
    return curves


def check_model(gmsh) -> dict:
    """Check the current gmsh model (see the module docstring); returns its groups and sizes."""
    model = gmsh.model
    name_of = {}
    for dim, tag in model.getPhysicalGroups():
        name_of[(dim, tag)] = model.getPhysicalName(dim, tag) or str(tag)
    types3, _, _ = model.mesh.getElements(3)
    if model.getDimension() == 3 or len(types3):
        raise ModelError("a 3D model: only 2D bodies (plane stress/strain) are supported")
    types2, tags2, _ = model.mesh.getElements(2)
    if len(types2) == 0:
        raise ModelError("no 2D elements: the model has no meshed surface")
    if any(t != GMSH_TRIANGLE for t in types2):
        names = sorted({model.mesh.getElementProperties(int(t))[0] for t in types2})
        raise ModelError(f"element types {', '.join(names)}: only linear triangles are supported "
                         "(no quadrangles, mixed or curved second-order meshes; use degree: 2 for P2 fields)")
    node_tags, coords, _ = model.mesh.getNodes()
    x = coords.reshape(-1, 3)
    if not np.all(np.isfinite(x)):
        raise ModelError("node coordinates that are not finite numbers")
    scale = max(float(np.max(np.abs(x[:, :2]))), 1e-300)
    if np.max(np.abs(x[:, 2])) > 1e-12 * scale:
        raise ModelError("nodes with z != 0: the body must lie in the plane z = 0")
    if len(node_tags) == 0 or node_tags.min() < 1 or node_tags.max() > len(node_tags):
        raise ModelError("node numbering gmsh could not renumber 1..N")
    pos = np.empty(int(node_tags.max()) + 1, dtype=np.int64)
    pos[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    _check_groups(model, name_of)
    # Orientation and area of every triangle
    _, conn = model.mesh.getElementsByType(GMSH_TRIANGLE)
    conn = conn.astype(np.int64)
    if len(conn) == 0 or conn.min() < 1 or conn.max() > node_tags.max():
        raise ModelError("triangles that name nodes the file does not define")
    tri = pos[conn.reshape(-1, 3)]
    p = x[tri, :2]
    area2 = ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
             - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    amax = float(np.max(np.abs(area2)))
    if not np.isfinite(amax) or np.any(np.abs(area2) <= 1e-12 * amax):
        raise ModelError(f"{int(np.sum(~(np.abs(area2) > 1e-12 * amax)))} degenerate (zero-area) triangles")
    npos, nneg = int(np.sum(area2 > 0)), int(np.sum(area2 < 0))
    if npos and nneg:
        raise ModelError(f"inverted elements: {min(npos, nneg)} of {len(area2)} triangles are "
                         "oriented opposite to the others")
    # boundary edges of the body: edges of exactly one triangle (keys of sorted vertex pairs)
    edges = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    ekeys, ecount = np.unique(edges[:, 0] * len(node_tags) + edges[:, 1], return_counts=True)
    boundary = ekeys[ecount == 1]
    curves, surfaces, curve_nodes, inner = _group_sizes(model, name_of, pos, len(node_tags), boundary)
    if not surfaces:
        raise ModelError("no physical surface: define one (the body and its material)")
    n_edges = len(ekeys)
    bbox = [float(x[:, 0].min()), float(x[:, 1].min()), float(x[:, 0].max()), float(x[:, 1].max())]
    return {"curves": curves, "surfaces": surfaces, "curve_nodes": curve_nodes, "inner_segments": inner, "n_nodes": int(len(node_tags)),
            "n_triangles": int(len(area2)), "n_edges": int(n_edges), "bbox": bbox,
            "names": [[int(d), gmsh.model.getPhysicalName(d, t) or str(t), int(t)]
                      for d, t in gmsh.model.getPhysicalGroups()]}


def _check_groups(model, name_of: dict) -> None:
    """Every meshed surface entity in exactly one physical surface; every curve in at most one."""
    for dim in (1, 2):
        for _, ent in model.getEntities(dim):
            groups = [name_of[(dim, g)] for g in model.getPhysicalGroupsForEntity(dim, ent)]
            types, _, _ = model.mesh.getElements(dim, ent)
            if len(groups) > 1:
                kind = "surface" if dim == 2 else "curve"
                raise ModelError(f"{kind} {ent} is in several physical groups ({', '.join(groups)}): each must be in one")
            if dim == 2 and len(types) and not groups:
                raise ModelError(f"surface {ent} is meshed but in no physical surface: "
                                 "put every surface of the body in a physical surface (its material)")


def _group_sizes(model, name_of: dict, pos: np.ndarray, n_nodes: int, boundary: np.ndarray):
    """Per physical curve (tag, elements), its number of nodes and of line elements that are no
    boundary edge of the body; per physical surface (tag, elements)."""
    curves, surfaces, curve_nodes, inner = {}, {}, {}, {}
    for (dim, tag), name in name_of.items():
        count, nodes, segs = 0, [], []
        for ent in model.getEntitiesForPhysicalGroup(dim, tag):
            types, etags, enodes = model.mesh.getElements(dim, ent)
            count += sum(len(t) for t in etags)
            nodes.extend(np.asarray(n).tolist() for n in enodes)
            segs.extend(np.asarray(n, dtype=np.int64).reshape(-1, 2)[:, :2] for t, n in zip(types, enodes)
                        if t == GMSH_LINE)
        if dim == 1:
            curves[name] = (int(tag), int(count))
            curve_nodes[name] = int(len(np.unique(np.concatenate(nodes)))) if nodes else 0
            if segs:                    # line elements of the curve that are no boundary edge
                seg = np.sort(pos[np.concatenate(segs)], axis=1)
                inner[name] = int(np.sum(~np.isin(seg[:, 0] * n_nodes + seg[:, 1], boundary)))
        elif dim == 2:
            surfaces[name] = (int(tag), int(count))
    return curves, surfaces, curve_nodes, inner


def extract(gmsh) -> dict:
    """The arrays of gmsh's current model as :func:`dolfinx.io.gmshio.model_to_mesh` extracts them
    (DOLFINx 0.5.2's ``extract_geometry`` and ``extract_topology_and_markers``, without DOLFINx,
    which this process does not load), in the layout of app/systems/mesh_arrays.py."""
    model = gmsh.model
    indices, points, _ = model.mesh.getNodes()
    points = points.reshape(-1, 3)
    x = points[np.argsort(indices - 1)]
    topologies: dict = {}
    for dim, tag in model.getPhysicalGroups():
        for entity in model.getEntitiesForPhysicalGroup(dim, tag):
            entity_types, entity_tags, entity_topologies = model.mesh.getElements(dim, tag=entity)
            if len(entity_types) == 0:
                continue
            if len(entity_types) != 1:
                raise ModelError(f"physical group {tag} mixes element types on entity {entity}")
            num_nodes = model.mesh.getElementProperties(entity_types[0])[3]
            topology = entity_topologies[0].reshape(-1, num_nodes) - 1
            marker = np.full_like(entity_tags[0], tag)
            t = int(entity_types[0])
            if t in topologies:
                topologies[t]["topology"] = np.concatenate((topologies[t]["topology"], topology), axis=0)
                topologies[t]["cell_data"] = np.hstack([topologies[t]["cell_data"], marker])
            else:
                topologies[t] = {"topology": topology, "cell_data": marker}
    dims = {t: model.mesh.getElementProperties(t)[1] for t in topologies}
    order = sorted(topologies, key=lambda t: dims[t])          # ascending dimension (as np.argsort)
    cell_id = order[-1]
    facet_id = order[-2] if len(order) > 1 and dims[order[-2]] == dims[cell_id] - 1 else -1
    k = model.mesh.getElementProperties(cell_id)[3]
    return {"x": np.asarray(x, dtype=np.float64),
            "cells": np.asarray(topologies[cell_id]["topology"], dtype=np.int64).reshape(-1, k),
            "cell_values": np.asarray(topologies[cell_id]["cell_data"], dtype=np.int32),
            "gmsh_cell": np.int64(cell_id),
            "facets": (np.asarray(topologies[facet_id]["topology"], dtype=np.int64) if facet_id != -1
                       else np.empty((0, 0), dtype=np.int64)),
            "facet_values": (np.asarray(topologies[facet_id]["cell_data"], dtype=np.int32) if facet_id != -1
                             else np.empty(0, dtype=np.int32)),
            "gmsh_facet": np.int64(facet_id)}


def main(argv: list[str]) -> int:
    """Read FILE into OUTDIR as the module docstring says (``argv``: FILE OUTDIR MAX_NODES
    MAX_ELEMENTS MAX_DOFS SIZE_FACTOR). Returns 0 when written, :data:`EXIT_MODEL_ERROR` with the
    one-line error in ``info.json`` when the checks or gmsh refuse the model; a MemoryError is not caught."""
    path, out = pathlib.Path(argv[0]), pathlib.Path(argv[1])
    max_nodes, max_elements, max_dofs = int(argv[2]), int(argv[3]), int(argv[4])
    size_factor = float(argv[5]) if len(argv) > 5 else 1.0
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))     # child_curves.py (python -I drops it)
    import gmsh
    gmsh.initialize([], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    try:
        curve_info, curve_arrays = open_model(gmsh, path, max_nodes, max_elements, max_dofs, size_factor)
        info = check_model(gmsh)
        arrays = extract(gmsh)
        info["obstacle_curves"], info["boundary_curves"] = curve_info
        arrays.update(curve_arrays)
    except ModelError as err:
        (out / "info.json").write_text(json.dumps({"error": str(err)}))
        return EXIT_MODEL_ERROR
    except MemoryError:
        raise
    except Exception as err:      # noqa: BLE001 - gmsh's own errors on a user's file
        (out / "info.json").write_text(json.dumps({"error": f"gmsh: {_short(err)}"}))
        return EXIT_MODEL_ERROR
    with open(out / "arrays.npz", "xb") as f:
        np.savez(f, **arrays)
    (out / "info.json").write_text(json.dumps(info))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
