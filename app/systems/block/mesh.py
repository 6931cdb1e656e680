"""Triangular meshes of the rectangular block [0, length] x [0, height].

Every pattern goes through gmsh the same way: the structured patterns are
built as exact numpy node/element arrays and handed to gmsh as a discrete
model, the unstructured one is meshed by gmsh from a built-in geometry.
The model is written to a ``.msh`` file, read back into a fresh gmsh model,
and the arrays :func:`dolfinx.io.gmshio.model_to_mesh` would distribute
(nodes, cells, marked facets) are cached on rank 0 in a ``.npz`` file
(written atomically, never over an existing file). A cached mesh is read
with numpy and distributed with :func:`dolfinx.mesh.create_mesh` exactly as
``model_to_mesh`` does, so gmsh is not even imported (0.2-0.4 s
of start-up) and the node/cell numbering is the same.

Physical groups (= DOLFINx facet/cell tag values)::

    D +---------- CD = 2 ----------+ C       y = height
      |                            |
      LATERAL = 3       cells = 1  LATERAL = 3
      |                            |
    A +---------- AB = 1 ----------+ B       y = 0
     x = 0                        x = length
"""

from __future__ import annotations

import hashlib
import pathlib
import tempfile
import uuid

import dolfinx.mesh
import numpy as np
import numpy.typing as npt
from dolfinx.cpp.mesh import MeshTags_int32
from mpi4py import MPI

from app.common.cache import APP_NAME, CacheUnusable, cache_dir, usable_dir
from app.systems import mesh_arrays
from app.systems.gmsh.mesh import GMSH_LINE, GMSH_TRIANGLE, gmsh_initialize

__all__ = ["AB", "CD", "LATERAL", "CELLS", "PATTERNS", "DEFAULT_CACHE_DIR", "block_mesh",
           "structured_triangulation", "mesh_file_name"]

AB, CD, LATERAL = 1, 2, 3
CELLS = 1
PATTERNS = ("crossed", "right", "left", "alternate", "unstructured")
DEFAULT_CACHE_DIR = pathlib.Path(__file__).resolve().parents[3] / "meshes"

def user_cache_dir() -> pathlib.Path:
    """``$XDG_CACHE_HOME/contact-divergence/meshes``, else ``~/.cache/contact-divergence/meshes``,
    else this user's folder in the temporary folder (app/common/cache.py: a relative
    ``XDG_CACHE_HOME`` is ignored, as the XDG base directory specification says; an unusable one
    falls back with a warning; :class:`app.common.cache.CacheUnusable` when nothing works)."""
    return cache_dir(f"{APP_NAME}/meshes")


def mesh_cache_path(name: str, install_dir: pathlib.Path | None = None) -> pathlib.Path:
    """Where the mesh file ``name`` is read from or written to.

    A file already in the install folder (``meshes/``) is used; a new mesh is written there if
    that folder is writable, else to the user's cache folder (:func:`user_cache_dir`), so a user
    without write access to the installation can still run any mesh.
    """
    install_dir = pathlib.Path(DEFAULT_CACHE_DIR if install_dir is None else install_dir)
    if (install_dir / name).is_file() or usable_dir(install_dir) is None:
        return install_dir / name
    return user_cache_dir() / name


# Bump when the generated meshes change, so that stale cache files are not reused.
_GENERATOR_VERSION = 1


def structured_triangulation(length: float, height: float, nx: int, ny: int,
                             pattern: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Nodes and counter-clockwise triangles of a structured mesh of the block.

    Grid node (i, j), 0 <= i <= nx, 0 <= j <= ny, has index j*(nx+1) + i.
    For ``pattern == "crossed"`` the centre of cell (i, j) follows as node
    (nx+1)*(ny+1) + j*nx + i.

    Parameters
    ----------
    length
        Length of the block (x direction).
    height
        Height of the block (y direction).
    nx
        Number of cells along x.
    ny
        Number of cells along y.
    pattern
        "crossed" (4 triangles per cell), "right" (diagonal from
        lower left to upper right), "left" (lower right to upper
        left) or "alternate" (checkerboard of right and left).

    Returns
    -------
    x
        Node coordinates, of shape (num_nodes, 2).
    cells
        Zero-based triangle connectivity, of shape (num_cells, 3).
    """
    if pattern not in ("crossed", "right", "left", "alternate"):
        raise ValueError(f"Not a structured pattern: {pattern!r}")
    if nx < 1 or ny < 1:
        raise ValueError(f"nx and ny must be positive, got nx={nx}, ny={ny}")

    xs = np.linspace(0.0, length, nx + 1)
    ys = np.linspace(0.0, height, ny + 1)
    X, Y = np.meshgrid(xs, ys)  # shape (ny+1, nx+1): row j, column i
    x = np.column_stack([X.ravel(), Y.ravel()])

    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    i, j = i.ravel(), j.ravel()
    v0 = j * (nx + 1) + i  # lower left
    v1 = v0 + 1            # lower right
    v2 = v0 + (nx + 1)     # upper left
    v3 = v2 + 1            # upper right

    if pattern == "crossed":
        c = (nx + 1) * (ny + 1) + j * nx + i
        centres = np.column_stack([(xs[i] + xs[i + 1]) / 2, (ys[j] + ys[j + 1]) / 2])
        x = np.vstack([x, centres])
        # Four triangles per cell, stored cell by cell: bottom, right, top, left
        cells = np.stack([np.column_stack([v0, v1, c]), np.column_stack([v1, v3, c]),
                          np.column_stack([v3, v2, c]), np.column_stack([v2, v0, c])], axis=1)
    else:
        right = np.stack([np.column_stack([v0, v1, v3]), np.column_stack([v0, v3, v2])], axis=1)
        left = np.stack([np.column_stack([v0, v1, v2]), np.column_stack([v1, v3, v2])], axis=1)
        if pattern == "right":
            use_right = np.ones(i.shape, dtype=bool)
        elif pattern == "left":
            use_right = np.zeros(i.shape, dtype=bool)
        else:
            use_right = (i + j) % 2 == 0
        cells = np.where(use_right[:, None, None], right, left)
    return x, cells.reshape(-1, 3).astype(np.int64)


def mesh_file_name(length: float, height: float, nx: int, ny: int, pattern: str,
                   mesh_size: float | None = None) -> str:
    """Readable, parameter-hashed cache file name of a block mesh."""
    key = repr((_GENERATOR_VERSION, float(length), float(height), int(nx), int(ny), pattern,
                None if mesh_size is None else float(mesh_size)))
    digest = hashlib.sha1(key.encode()).hexdigest()[:10]
    if pattern == "unstructured":
        readable = f"unstructured_h{mesh_size:g}"
    else:
        readable = f"{pattern}_{nx}x{ny}"
    return f"block_{readable}_{length:g}x{height:g}_{digest}.npz"


def _add_structured_model(gmsh, length: float, height: float, nx: int, ny: int, pattern: str) -> None:
    """Fill the current (empty) gmsh model with a discrete structured mesh."""
    x, cells = structured_triangulation(length, height, nx, ny, pattern)
    num_nodes = x.shape[0]

    # Discrete entities: surface 1, curves AB=1, CD=2, x=0 -> 3, x=length -> 4
    gmsh.model.addDiscreteEntity(2, 1)
    for tag in (1, 2, 3, 4):
        gmsh.model.addDiscreteEntity(1, tag)

    # All nodes live on the surface; gmsh node tags are 1..num_nodes
    coords = np.column_stack([x, np.zeros(num_nodes)])
    gmsh.model.mesh.addNodes(2, 1, np.arange(1, num_nodes + 1), coords.ravel())
    gmsh.model.mesh.addElementsByType(1, GMSH_TRIANGLE, np.arange(1, cells.shape[0] + 1),
                                      (cells + 1).ravel())

    # Boundary edges (node index 0-based on the (nx+1) x (ny+1) grid)
    bottom = np.arange(nx + 1)
    top = ny * (nx + 1) + np.arange(nx + 1)
    left = np.arange(ny + 1) * (nx + 1)
    right = left + nx
    next_tag = cells.shape[0] + 1
    for curve, chain in ((1, bottom), (2, top), (3, left), (4, right)):
        edges = np.column_stack([chain[:-1], chain[1:]]) + 1
        gmsh.model.mesh.addElementsByType(curve, GMSH_LINE,
                                          np.arange(next_tag, next_tag + edges.shape[0]), edges.ravel())
        next_tag += edges.shape[0]

    gmsh.model.addPhysicalGroup(2, [1], CELLS)
    gmsh.model.addPhysicalGroup(1, [1], AB)
    gmsh.model.addPhysicalGroup(1, [2], CD)
    gmsh.model.addPhysicalGroup(1, [3, 4], LATERAL)
    gmsh.model.setPhysicalName(1, AB, "AB")
    gmsh.model.setPhysicalName(1, CD, "CD")
    gmsh.model.setPhysicalName(1, LATERAL, "lateral")
    gmsh.model.setPhysicalName(2, CELLS, "block")


def _add_unstructured_model(gmsh, length: float, height: float, mesh_size: float) -> None:
    """Fill the current (empty) gmsh model with an unstructured mesh of the block."""
    geo = gmsh.model.geo
    pts = [geo.addPoint(0.0, 0.0, 0.0, mesh_size), geo.addPoint(length, 0.0, 0.0, mesh_size),
           geo.addPoint(length, height, 0.0, mesh_size), geo.addPoint(0.0, height, 0.0, mesh_size)]
    ab = geo.addLine(pts[0], pts[1])
    bc = geo.addLine(pts[1], pts[2])
    cd = geo.addLine(pts[2], pts[3])
    da = geo.addLine(pts[3], pts[0])
    loop = geo.addCurveLoop([ab, bc, cd, da])
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()

    gmsh.model.addPhysicalGroup(2, [surface], CELLS)
    gmsh.model.addPhysicalGroup(1, [ab], AB)
    gmsh.model.addPhysicalGroup(1, [cd], CD)
    gmsh.model.addPhysicalGroup(1, [bc, da], LATERAL)
    gmsh.model.setPhysicalName(1, AB, "AB")
    gmsh.model.setPhysicalName(1, CD, "CD")
    gmsh.model.setPhysicalName(1, LATERAL, "lateral")
    gmsh.model.setPhysicalName(2, CELLS, "block")

    gmsh.option.setNumber("Mesh.MeshSizeMin", mesh_size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
    gmsh.model.mesh.generate(2)
    # model_to_mesh needs node tags 1..N
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()


def _generate(length: float, height: float, nx: int, ny: int, pattern: str,
              mesh_size: float | None) -> mesh_arrays.MeshArrays:
    """Build the block's gmsh model, write it to a temporary ``.msh``, read it back into a fresh
    model and extract the arrays ``model_to_mesh`` distributes (rank-0 only; imports gmsh)."""
    gmsh, initialized_here = gmsh_initialize()
    previous = gmsh.model.getCurrent() if not initialized_here else None
    names = []
    try:
        names.append(f"block_build_{uuid.uuid4().hex[:8]}")
        gmsh.model.add(names[-1])
        if pattern == "unstructured":
            _add_unstructured_model(gmsh, length, height, mesh_size)
        else:
            _add_structured_model(gmsh, length, height, nx, ny, pattern)
        with tempfile.TemporaryDirectory(prefix="block-mesh-") as tmp:
            msh = pathlib.Path(tmp) / "block.msh"     # gmsh picks the format from the extension
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.option.setNumber("Mesh.Binary", 0)
            gmsh.option.setNumber("Mesh.SaveAll", 0)
            gmsh.write(str(msh))
            names.append(f"block_{uuid.uuid4().hex[:8]}")
            gmsh.model.add(names[-1])
            gmsh.merge(str(msh))
        return mesh_arrays.extract(gmsh)
    finally:
        if initialized_here:
            gmsh.finalize()
        else:
            for name in names:
                if name in gmsh.model.list():
                    gmsh.model.setCurrent(name)
                    gmsh.model.remove()
            if previous in gmsh.model.list():
                gmsh.model.setCurrent(previous)


def _cached_arrays(path: pathlib.Path, length: float, height: float, nx: int, ny: int, pattern: str,
                   mesh_size: float | None) -> mesh_arrays.MeshArrays:
    """The mesh arrays of ``path`` (numpy only), generated and cached first if the file is missing."""
    if path.exists():
        return mesh_arrays.load(path)
    arrays = _generate(length, height, nx, ny, pattern, mesh_size)
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh_arrays.save(arrays, path)
    return arrays


def block_mesh(comm: MPI.Comm, length: float, height: float, nx: int, ny: int, pattern: str,
               mesh_size: float | None = None,
               cache_dir: pathlib.Path | None = None) -> tuple[dolfinx.mesh.Mesh, MeshTags_int32]:
    """Distributed triangular mesh of the block with tagged facets (collective).

    The mesh is generated on rank 0 of ``comm`` with gmsh and its arrays cached in ``cache_dir``
    as a ``.npz`` file (reused if present: gmsh is then not imported), and distributed over
    ``comm`` as :func:`dolfinx.io.gmshio.model_to_mesh` would (app/systems/mesh_arrays.py).

    Parameters
    ----------
    comm
        MPI communicator of the mesh.
    length
        Length of AB (x direction), in mm.
    height
        Height of the block (y direction), in mm.
    nx
        Number of cells along x (structured patterns).
    ny
        Number of cells along y (structured patterns).
    pattern
        One of :data:`PATTERNS`.
    mesh_size
        Target element size (required for "unstructured",
        ignored otherwise).
    cache_dir
        Directory of the cached ``.npz`` files (None: the install folder's
        ``meshes/`` if writable, else the user's cache folder, :func:`mesh_cache_path`).

    Returns
    -------
    mesh
        The distributed mesh.
    facet_tags
        Its facet tags :data:`AB`, :data:`CD` and :data:`LATERAL`.
    """
    if pattern not in PATTERNS:
        raise ValueError(f"Unknown pattern {pattern!r}, expected one of {PATTERNS}")
    if not (length > 0 and height > 0):
        raise ValueError(f"length and height must be positive, got {length}, {height}")
    if pattern == "unstructured":
        if mesh_size is None or not mesh_size > 0:
            raise ValueError("pattern 'unstructured' needs a positive mesh_size")
    else:
        mesh_size = None
        if nx < 1 or ny < 1:
            raise ValueError(f"nx and ny must be positive, got nx={nx}, ny={ny}")

    root = 0
    name = mesh_file_name(length, height, nx, ny, pattern, mesh_size)
    path = pathlib.Path(cache_dir) / name if cache_dir is not None else None

    # Rank 0 reads (or generates and caches) the arrays; errors are broadcast so that no rank
    # is left waiting in the distribution.
    error, arrays, no_cache = None, None, None
    if comm.rank == root:
        try:
            arrays = _cached_arrays(path if path is not None else mesh_cache_path(name), length, height, nx, ny,
                                    pattern, mesh_size)
        except CacheUnusable as e:
            no_cache = str(e)
        except Exception as e:  # noqa: BLE001 -- re-raised on every rank below
            error = f"{type(e).__name__}: {e}"
    error, no_cache = comm.bcast((error, no_cache), root=root)          # MPI collective
    if no_cache is not None:
        raise CacheUnusable(no_cache)
    if error is not None:
        raise RuntimeError(f"block_mesh: mesh generation failed on rank {root}: {error}")
    mesh, _cell_tags, facet_tags = mesh_arrays.build(comm, arrays, root, gdim=2)     # MPI collective
    mesh.name = pathlib.Path(name).stem
    facet_tags.name = "facet_tags"
    return mesh, facet_tags
