"""Read a user's 2D Gmsh model (``.geo`` or ``.msh``) as data, never as code in the app's process.

A ``.geo`` is first checked against the allowlist of app/systems/gmsh/geo_allowlist.py, a ``.msh``
against its headers (app/systems/gmsh/msh_header.py: it must start with ``$MeshFormat``, counts
within the limits); then Gmsh reads and meshes it in the sandboxed child of
app/systems/gmsh/sandbox.py, which checks the model (app/systems/gmsh/child.py: 2D, linear
triangles, physical groups, orientation) and returns its groups, sizes and the arrays DOLFINx
0.5.2's :func:`dolfinx.io.gmshio.model_to_mesh` would extract (its ``read_from_msh`` is broken,
see docs/limitations.md). Every problem is a one-line :class:`app.systems.schema.SystemPathError` on the key
``file`` (``resource=True`` on the error for the time and memory limits: exit status 4). The result
is cached per file version, so validating a scene and building it run Gmsh once.
"""
from __future__ import annotations

import pathlib
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from app.common.runtime import import_gmsh
from app.systems.schema import SystemPathError, file_version

GMSH_LINE, GMSH_TRIANGLE = 1, 2
_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()     # (file version, size factor) -> (info, arrays, limits)
_CACHE_SIZE = 4


@dataclass(frozen=True)
class ModelInfo:
    """What a scene may refer to in a Gmsh model, and its sizes."""

    curves: dict[str, tuple[int, int]]        # physical curve name -> (tag, number of line elements)
    surfaces: dict[str, tuple[int, int]]      # physical surface name -> (tag, number of triangles)
    n_nodes: int
    n_triangles: int
    bbox: tuple[float, float, float, float] = field(default=(0.0, 0.0, 0.0, 0.0))   # xmin, ymin, xmax, ymax
    n_edges: int = 0                                              # triangle edges (the P2 mid-side nodes)
    curve_nodes: dict[str, int] = field(default_factory=dict)     # physical curve name -> its vertices
    names: dict[tuple[int, str], int] = field(default_factory=dict)   # (dim, name) -> physical tag
    inner_segments: dict[str, int] = field(default_factory=dict)   # physical curve -> line elements off the boundary
    # free physical curves (bounding no surface; not the body's): name -> {"entities", "panels", "error"}
    obstacle_curves: dict[str, dict] = field(default_factory=dict)
    # the other physical curves (a body's), sampled alike: an obstacle body's contact curve
    boundary_curves: dict[str, dict] = field(default_factory=dict)

    def dofs(self, degree: int) -> int:
        """DOFs of the whole body (2 per node; P2 adds a node per edge) before any is prescribed."""
        return 2 * (self.n_nodes + (self.n_edges if degree == 2 else 0))

    def contact_nodes(self, curve: str, degree: int) -> int:
        """Nodes of a physical curve (P2 adds a mid-side node per line element)."""
        return self.curve_nodes.get(curve, 0) + (self.curves[curve][1] if degree == 2 and curve in self.curves else 0)


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
    gmsh = import_gmsh()
    here = False
    if not gmsh_is_initialized(gmsh):
        gmsh.initialize()
        here = True
    gmsh.option.setNumber("General.Terminal", 0)
    return gmsh, here


def _limits(limits):
    from app.systems.gmsh.sandbox import SandboxLimits
    from app.systems.schema import Limits
    return SandboxLimits.from_limits(limits if limits is not None else Limits())


def _read(path: pathlib.Path, value: str, limits, roots, size_factor: float = 1.0) -> tuple[ModelInfo, dict]:
    """Check and read ``path`` in the sandbox (cached per file version, size factor and limits);
    a ``.geo`` is meshed with its characteristic lengths times ``size_factor``."""
    lim = _limits(limits)
    try:
        key = (file_version(path), float(size_factor))
    except OSError as err:
        raise SystemPathError("file", value, f"cannot read {path.name}: {err.strerror or err}") from None
    if key in _CACHE and (limits is None or _CACHE[key][2] == lim):     # None: as validated
        _CACHE.move_to_end(key)
        found = _CACHE[key]
        if isinstance(found[0], SystemPathError):          # a refusal is remembered too: Gmsh runs once
            raise _refusal(value, found[0].msg, found[0].resource)
        return found[:2]
    try:
        info, arrays = _read_uncached(path, value, lim, roots, size_factor)
    except SystemPathError as err:
        _remember(key, (err, None, lim))
        raise
    _remember(key, (info, arrays, lim))
    return info, arrays


def _remember(key: tuple, entry: tuple) -> None:
    _CACHE[key] = entry
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)


def _refusal(value: str, msg: str, resource: bool = False) -> SystemPathError:
    """The one-line error on ``file``; ``resource``: a time or memory limit stopped the reading."""
    err = SystemPathError("file", value, msg)
    err.resource = resource
    return err


def _read_uncached(path: pathlib.Path, value: str, lim, roots, size_factor: float = 1.0) -> tuple[ModelInfo, dict]:
    from app.systems.gmsh import geo_allowlist, msh_header
    from app.systems.gmsh import sandbox as gmsh_sandbox
    suffix = path.suffix.lower()
    if suffix not in (".geo", ".msh"):
        raise _refusal(value, "allowed: a Gmsh .geo or .msh file")
    try:
        if suffix == ".geo":
            geo_allowlist.check_file(path, roots)
        else:
            msh_header.check(path, path.name, lim.max_nodes, lim.max_elements, lim.max_dofs)
        raw, arrays = gmsh_sandbox.read(path, lim, size_factor)
    except (geo_allowlist.GeoRefused, msh_header.MshRefused) as err:
        raise _refusal(value, str(err)) from None
    except gmsh_sandbox.SandboxError as err:
        raise _refusal(value, str(err), err.resource) from None
    _check_arrays(arrays, raw, value)
    info = ModelInfo(curves={k: (int(t), int(c)) for k, (t, c) in raw["curves"].items()},
                     surfaces={k: (int(t), int(c)) for k, (t, c) in raw["surfaces"].items()},
                     n_nodes=int(raw["n_nodes"]), n_triangles=int(raw["n_triangles"]), bbox=tuple(raw["bbox"]),
                     n_edges=int(raw["n_edges"]), curve_nodes={k: int(v) for k, v in raw["curve_nodes"].items()},
                     names={(int(d), str(n)): int(t) for d, n, t in raw["names"]},
                     inner_segments={k: int(v) for k, v in raw["inner_segments"].items()},
                     obstacle_curves=dict(raw.get("obstacle_curves") or {}),
                     boundary_curves=dict(raw.get("boundary_curves") or {}))
    return info, arrays


def _check_arrays(arrays: dict, raw: dict, value: str) -> None:
    """The child's arrays are consistent before DOLFINx sees them (indices within the nodes)."""
    x, cells = arrays.get("x"), arrays.get("cells")
    ok = (x is not None and cells is not None and x.ndim == 2 and x.shape[1] == 3 and np.all(np.isfinite(x))
          and cells.ndim == 2 and cells.size and int(arrays["gmsh_cell"]) == GMSH_TRIANGLE
          and cells.min() >= 0 and cells.max() < len(x) and len(arrays["cell_values"]) == len(cells))
    facets = arrays.get("facets")
    if ok and facets is not None and facets.size:
        ok = facets.min() >= 0 and facets.max() < len(x) and len(arrays["facet_values"]) == len(facets)
    if not ok:
        raise SystemPathError("file", value, "gmsh returned an inconsistent mesh (node numbers out of range)")
    cp, cxy = arrays.get("curve_params"), arrays.get("curve_xy")
    m = 0 if cp is None else len(cp)
    curves = {**(raw.get("obstacle_curves") or {}), **(raw.get("boundary_curves") or {})}
    if cp is not None and not (cp.ndim == 2 and cp.shape[1] == 2 and cxy is not None and cxy.ndim == 3
                               and cxy.shape[0] == m and cxy.shape[2] == 2 and np.all(np.isfinite(cp))
                               and np.all(np.isfinite(cxy)) and all(0 <= c["panels"][0] <= c["panels"][1] <= m
                                                                    for c in curves.values())):
        raise SystemPathError("file", value, "gmsh returned inconsistent samples of the free curves")


def obstacle_samples(path: pathlib.Path, name: str, size_factor: float = 1.0, bounding: bool = False
                     ) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
    """``(entities, params, xy, entity_of_panel)`` of the free physical curve ``name`` (``bounding``:
    of a curve of a surface) as the child sampled it (app/systems/gmsh/child_curves.py), from the
    model read at validation."""
    info, arrays = _read(path, path.name, None, None, size_factor)
    c = (info.boundary_curves if bounding else info.obstacle_curves)[name]
    a, b = c["panels"]
    return list(c["entities"]), arrays["curve_params"][a:b], arrays["curve_xy"][a:b], arrays["curve_entity"][a:b]


def model_info(path: pathlib.Path, value: str, limits=None, roots=None, size_factor: float = 1.0) -> ModelInfo:
    """Check and read a model file (cached per file version); raises :class:`SystemPathError`.

    ``limits``: the scene's ``settings.limits`` (defaults if None); ``roots``: folders a .geo may
    include files from (default: the .geo's own folder); ``size_factor``: a .geo's characteristic
    lengths are multiplied by it (``system.mesh_size_factor``)."""
    return _read(path, value, limits, roots, size_factor)[0]


def read_mesh(path: pathlib.Path, comm, limits=None, size_factor: float = 1.0):
    """Distributed DOLFINx mesh with cell and facet tags from the model file (MPI collective).

    Rank 0 reads the file in the sandbox (or takes the arrays cached by the validation);
    :func:`app.systems.mesh_arrays.build` distributes them as ``model_to_mesh`` does. Returns
    ``(mesh, cell_tags, facet_tags, names)`` with ``names[(dim, name)] = tag``.
    """
    from app.systems import mesh_arrays
    error, names, arrays = None, None, None
    if comm.rank == 0:
        try:
            info, raw = _read(path, str(path), limits, None, size_factor)
            names = dict(info.names)
            arrays = mesh_arrays.MeshArrays(
                x=raw["x"], cells=raw["cells"], cell_values=raw["cell_values"], gmsh_cell=int(raw["gmsh_cell"]),
                facets=raw["facets"], facet_values=raw["facet_values"], gmsh_facet=int(raw["gmsh_facet"]))
        except SystemPathError as err:   # re-raised on every rank below
            error = err.msg
    error = comm.bcast(error, root=0)                      # MPI collective
    if error is not None:
        raise RuntimeError(f"reading {path.name}: {error}")
    mesh, cell_tags, facet_tags = mesh_arrays.build(comm, arrays, 0, gdim=2)     # MPI collective
    names = comm.bcast(names, root=0)                      # MPI collective
    return mesh, cell_tags, facet_tags, names


def mesh_sizes(path: pathlib.Path, degree: int, prescribed: dict[str, str], contact: str,
               size_factor: float = 1.0) -> tuple[int, int]:
    """(DOFs after the Dirichlet reduction, contact nodes) of a body on the file's mesh, counted from
    the arrays read at validation (no assembly): a node of a prescribed curve loses the prescribed
    components, P2 adds a node per triangle edge; contact nodes with a prescribed component are
    left out of the contact set (app/systems/gmsh/operators.py)."""
    info, arrays = _read(path, path.name, None, None, size_factor)
    facets, values = arrays["facets"], arrays["facet_values"]
    p2 = degree == 2

    def of(curves) -> tuple[set, int]:
        tags = [info.names[(1, c)] for c in curves if (1, c) in info.names]
        rows = np.isin(values, tags) if len(values) else np.zeros(0, dtype=bool)
        return set(np.unique(facets[rows]).tolist()) if rows.any() else set(), int(rows.sum())
    dofs = 2 * info.n_nodes + (2 * info.n_edges if p2 else 0)
    fixed_nodes: set = set()
    for comp in ("x", "y"):
        nodes, n_facets = of([c for c, comps in prescribed.items() if comp in comps])
        dofs -= len(nodes) + (n_facets if p2 else 0)
        fixed_nodes |= nodes
    cnodes, c_facets = of([contact])
    return dofs, len(cnodes - fixed_nodes) + (c_facets if p2 else 0)


def obstacle_curve(path: pathlib.Path, shown: str, info: ModelInfo, obstacle, contact: str, size_factor: float = 1.0):
    """The :class:`app.loading.curve.SmoothCurve` of ``obstacle.physical``; one-line
    :class:`SystemPathError` on ``obstacle.physical`` for a curve that is missing, part of the
    body, from a ``.msh`` file, not smooth or too long to sample."""
    from app.loading.curve import CurveError, SmoothCurve
    name, key = obstacle.physical, "obstacle.physical"
    if name in info.curves and name not in info.obstacle_curves:     # (a .msh keeps its free curves' elements)
        raise SystemPathError(key, name, f"the physical curve '{name}' of {shown} is part of the body (it bounds or lies "
                              "in a surface): the obstacle must be a curve of its own, outside every surface")
    if name not in info.obstacle_curves:
        free = ", ".join(sorted(info.obstacle_curves)) or "none"
        raise SystemPathError(key, name, f"no physical curve '{name}' in {shown}; curves of their own (bounding no "
                              f"surface): {free}")
    entry = info.obstacle_curves[name]
    if entry.get("error"):
        raise SystemPathError(key, name, str(entry["error"]))
    entities, params, xy, ent_of = obstacle_samples(path, name, size_factor)
    bbox = info.bbox
    size = max(bbox[2] - bbox[0], bbox[3] - bbox[1], 1e-300)
    try:
        return SmoothCurve(name, entities, params, xy, ent_of, obstacle.side, size)
    except CurveError as err:
        raise SystemPathError(key, name, f"the curve '{name}' of {shown}: {err}") from None
