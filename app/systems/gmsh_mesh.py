"""Read a user's 2D Gmsh model (``.geo`` or ``.msh``) with Gmsh's own API, check it, and hand it
to DOLFINx 0.5.2's :func:`dolfinx.io.gmshio.model_to_mesh` (its ``read_from_msh`` is broken, see
NOTES.md).

Checks (each a one-line :class:`app.systems.schema.SystemPathError` on the key ``file``): the file
opens; the mesh is 2D (z = 0) with linear triangles only (no quadrangles: mixed meshes are not
supported by ``model_to_mesh``); every meshed surface belongs to exactly one physical surface
(elements outside physical groups would be silently dropped); every curve to at most one
physical curve; triangles have positive area and one orientation (a mix of orientations or a
zero area means inverted or degenerate elements). The result of the check is cached per file
version, so validating a scene and building it open the file once each.
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass, field

import numpy as np

from app.systems.schema import SystemPathError, file_version

GMSH_LINE, GMSH_TRIANGLE = 1, 2
_INFO_CACHE: dict[tuple, "ModelInfo"] = {}


@dataclass(frozen=True)
class ModelInfo:
    """What a scene may refer to in a Gmsh model."""
    curves: dict[str, tuple[int, int]]        # physical curve name -> (tag, number of line elements)
    surfaces: dict[str, tuple[int, int]]      # physical surface name -> (tag, number of triangles)
    n_nodes: int
    n_triangles: int
    bbox: tuple[float, float, float, float] = field(default=(0.0, 0.0, 0.0, 0.0))   # xmin, ymin, xmax, ymax


def gmsh_is_initialized(gmsh) -> bool:
    """Whether the gmsh API is initialized (gmsh 4.8 has no ``gmsh.isInitialized``)."""
    try:
        # Options are only populated between initialize() and finalize();
        # after finalize() the call raises.
        return bool(gmsh.option.getString("General.BuildInfo"))
    except Exception:
        return False


def gmsh_initialize():
    """The gmsh module, initialised (quietly); returns (gmsh, initialised_here)."""
    import gmsh
    here = False
    if not gmsh_is_initialized(gmsh):
        gmsh.initialize()
        here = True
    gmsh.option.setNumber("General.Terminal", 0)
    return gmsh, here


def open_model(gmsh, path: pathlib.Path, value: str) -> None:
    """Load ``path`` into a new current gmsh model, meshing a ``.geo`` in 2D; renumber nodes and
    elements 1..N (model_to_mesh needs it)."""
    gmsh.model.add(f"user_{abs(hash(str(path))) % 10**8}")
    try:
        gmsh.open(str(path))
    except Exception as err:        # noqa: BLE001 - the user's file
        raise SystemPathError("file", value, f"gmsh cannot open {path.name}: {' '.join(str(err).split())[:160]}") from None
    if path.suffix.lower() == ".geo":
        types, _, _ = gmsh.model.mesh.getElements(2)
        if len(types) == 0:
            try:
                gmsh.model.mesh.generate(2)
            except Exception as err:    # noqa: BLE001
                raise SystemPathError("file", value, f"gmsh cannot mesh {path.name}: "
                                      f"{' '.join(str(err).split())[:160]}") from None
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()


def check_model(gmsh, value: str) -> ModelInfo:
    """Check the current gmsh model (see the module docstring); returns its physical groups."""
    model = gmsh.model
    name_of = {}
    for dim, tag in model.getPhysicalGroups():
        name_of[(dim, tag)] = model.getPhysicalName(dim, tag) or str(tag)
    types3, _, _ = model.mesh.getElements(3)
    if model.getDimension() == 3 or len(types3):
        raise SystemPathError("file", value, "a 3D model: only 2D bodies (plane stress/strain) are supported")
    types2, tags2, _ = model.mesh.getElements(2)
    if len(types2) == 0:
        raise SystemPathError("file", value, "no 2D elements: the model has no meshed surface")
    if any(t != GMSH_TRIANGLE for t in types2):
        names = sorted({model.mesh.getElementProperties(int(t))[0] for t in types2})
        raise SystemPathError("file", value, f"element types {', '.join(names)}: only linear triangles are supported "
                              "(no quadrangles, mixed or curved second-order meshes; use degree: 2 for P2 fields)")
    node_tags, coords, _ = model.mesh.getNodes()
    x = coords.reshape(-1, 3)
    scale = max(float(np.max(np.abs(x[:, :2]))), 1e-300)
    if np.max(np.abs(x[:, 2])) > 1e-12 * scale:
        raise SystemPathError("file", value, "nodes with z != 0: the body must lie in the plane z = 0")
    pos = np.empty(int(node_tags.max()) + 1, dtype=np.int64)
    pos[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    # Every meshed surface entity in exactly one physical surface; every curve in at most one.
    for dim in (1, 2):
        for _, ent in model.getEntities(dim):
            groups = [name_of[(dim, g)] for g in model.getPhysicalGroupsForEntity(dim, ent)]
            types, _, _ = model.mesh.getElements(dim, ent)
            if len(groups) > 1:
                kind = "surface" if dim == 2 else "curve"
                raise SystemPathError("file", value, f"{kind} {ent} is in several physical groups "
                                      f"({', '.join(groups)}): each must be in one")
            if dim == 2 and len(types) and not groups:
                raise SystemPathError("file", value, f"surface {ent} is meshed but in no physical surface: "
                                      "put every surface of the body in a physical surface (its material)")
    # Orientation and area of every triangle
    _, conn = model.mesh.getElementsByType(GMSH_TRIANGLE)
    tri = pos[conn.astype(np.int64).reshape(-1, 3)]
    p = x[tri, :2]
    area2 = ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
             - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    amax = float(np.max(np.abs(area2)))
    if np.any(np.abs(area2) <= 1e-12 * amax):
        raise SystemPathError("file", value, f"{int(np.sum(np.abs(area2) <= 1e-12 * amax))} degenerate (zero-area) "
                              "triangles")
    npos, nneg = int(np.sum(area2 > 0)), int(np.sum(area2 < 0))
    if npos and nneg:
        raise SystemPathError("file", value, f"inverted elements: {min(npos, nneg)} of {len(area2)} triangles are "
                              "oriented opposite to the others")
    curves, surfaces = {}, {}
    for (dim, tag), name in name_of.items():
        count = 0
        for ent in model.getEntitiesForPhysicalGroup(dim, tag):
            types, etags, _ = model.mesh.getElements(dim, ent)
            count += sum(len(t) for t in etags)
        if dim == 1:
            curves[name] = (tag, count)
        elif dim == 2:
            surfaces[name] = (tag, count)
    if not surfaces:
        raise SystemPathError("file", value, "no physical surface: define one (the body and its material)")
    bbox = (float(x[:, 0].min()), float(x[:, 1].min()), float(x[:, 0].max()), float(x[:, 1].max()))
    return ModelInfo(curves=curves, surfaces=surfaces, n_nodes=len(node_tags), n_triangles=len(area2), bbox=bbox)


def model_info(path: pathlib.Path, value: str) -> ModelInfo:
    """Open and check a model file (cached per file version); raises :class:`SystemPathError`."""
    key = file_version(path)
    if key in _INFO_CACHE:
        return _INFO_CACHE[key]
    if path.suffix.lower() not in (".geo", ".msh"):
        raise SystemPathError("file", value, "allowed: a Gmsh .geo or .msh file")
    gmsh, here = gmsh_initialize()
    previous = gmsh.model.getCurrent() if not here else None
    try:
        open_model(gmsh, path, value)
        info = check_model(gmsh, value)
    except SystemPathError:
        raise
    except Exception as err:     # noqa: BLE001 - gmsh's own errors on a user's file
        raise SystemPathError("file", value, f"gmsh: {' '.join(str(err).split())[:160]}") from None
    finally:
        gmsh.model.remove()
        if here:
            gmsh.finalize()
        elif previous in gmsh.model.list():
            gmsh.model.setCurrent(previous)
    _INFO_CACHE[key] = info
    return info


def read_mesh(path: pathlib.Path, comm):
    """Distributed DOLFINx mesh with cell and facet tags from the model file (MPI collective).

    Rank 0 opens the file with gmsh and extracts the arrays ``model_to_mesh`` would;
    :func:`app.systems.mesh_arrays.build` distributes them as ``model_to_mesh`` does (the other
    ranks do not import gmsh). Returns ``(mesh, cell_tags, facet_tags, names)`` with
    ``names[(dim, name)] = tag``.
    """
    from app.systems import mesh_arrays
    error, names, arrays, here = None, None, None, False
    gmsh = None
    if comm.rank == 0:
        try:
            gmsh, here = gmsh_initialize()
            open_model(gmsh, path, str(path))
            check_model(gmsh, str(path))
            names = {(d, gmsh.model.getPhysicalName(d, t) or str(t)): t for d, t in gmsh.model.getPhysicalGroups()}
            arrays = mesh_arrays.extract(gmsh)
        except Exception as err:   # noqa: BLE001 - re-raised on every rank below
            error = str(err)
        finally:
            if gmsh is not None:
                gmsh.model.remove()
                if here:
                    gmsh.finalize()
    error = comm.bcast(error, root=0)                      # MPI collective
    if error is not None:
        raise RuntimeError(f"reading {path.name}: {error}")
    mesh, cell_tags, facet_tags = mesh_arrays.build(comm, arrays, 0, gdim=2)     # MPI collective
    names = comm.bcast(names, root=0)                      # MPI collective
    return mesh, cell_tags, facet_tags, names
