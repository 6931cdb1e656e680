"""Samples of the physical curves of a ``.geo`` model, taken in the sandboxed child
(app/systems/gmsh/child.py) while the gmsh model exists; imports only numpy.

A physical curve none of whose entities bounds a surface or is embedded in one is not part of
the body: it may be a
rigid obstacle (``system.obstacle: {type: curve, physical: NAME}``, app/loading/curve.py). Each of
its entities is sampled on its own parameter range ``[a, b]`` (gmsh.model.getParametrizationBounds)
by panels, each carrying the positions (gmsh.model.getValue) at the ``DEGREE + 1`` Chebyshev-Lobatto
points ``xi_k = cos(pi k / DEGREE)`` of the panel. A panel is accepted when the interpolating
polynomial of degree ``DEGREE`` matches gmsh's positions at the ``DEGREE`` points half-way between
the nodes (``cos(pi (k + 1/2) / DEGREE)``) to ``tol`` (:func:`tolerance`), else it is bisected.
Only positions are used: gmsh 4.8's built-in kernel returns its derivatives by finite differences
(errors about 1e-8 of the size for the first, of order one for the second), so the derivatives and
the curvature are those of the interpolants. The number of gmsh evaluations is checked against
``MAX_SAMPLES`` *before* each batch is asked for; a panel narrower than ``2^-MAX_DEPTH`` of its
entity's range stops the sampling (a corner or a cusp inside the entity).

Entities of a ``.msh`` file are discrete (only their mesh): no samples, ``error`` says so.
"""
from __future__ import annotations

import numpy as np

DEGREE = 12                   # per panel: Chebyshev interpolation of this degree
MAX_SAMPLES = 60000           # gmsh evaluations per file (nodes and test points of every panel tried)
MAX_DEPTH = 40                # bisections of an entity's parameter range
NODES = np.cos(np.pi * np.arange(DEGREE + 1) / DEGREE)          # Chebyshev-Lobatto points, 1 .. -1
TESTS = np.cos(np.pi * (np.arange(DEGREE) + 0.5) / DEGREE)      # half-way between them


class SampleError(Exception):
    """The curve cannot be sampled: ``str(err)`` is the one-line reason."""


def tolerance(body_size: float, coords: float) -> float:
    """Accepted interpolation error: 1e-11 of the body's size, not below the round-off of gmsh's
    positions (1000 eps of their magnitude)."""
    return max(1e-11 * body_size, 1e3 * np.finfo(float).eps * coords)


def free_curves(gmsh) -> dict[str, list[int]]:
    """Physical curves whose entities neither bound nor are embedded in a surface
    (``Curve{..} In Surface{..}``): name -> entity tags (as listed)."""
    embedded = {int(t) for _, s in gmsh.model.getEntities(2) for d, t in gmsh.model.mesh.getEmbedded(2, s) if d == 1}
    out = {}
    for dim, tag in gmsh.model.getPhysicalGroups(1):
        ents = [int(e) for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)]
        if ents and all(len(gmsh.model.getAdjacencies(1, e)[0]) == 0 and e not in embedded for e in ents):
            out[gmsh.model.getPhysicalName(dim, tag) or str(tag)] = ents
    return out


class _Budget:
    def __init__(self, limit: int):
        self.left = limit

    def take(self, n: int, name: str) -> None:
        if n > self.left:
            raise SampleError(f"the curve '{name}' needs more than {MAX_SAMPLES} gmsh evaluations to be resolved to "
                              "1e-11 of the body's size (with the file's other free curves): use a smoother or "
                              "shorter curve, or fewer free curves")
        self.left -= n


def _positions(gmsh, ent: int, u: np.ndarray) -> np.ndarray:
    xyz = np.asarray(gmsh.model.getValue(1, ent, u.tolist()), dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(xyz)):
        raise SampleError(f"curve {ent}: gmsh returns positions that are not finite numbers")
    return xyz


def sample_entity(gmsh, ent: int, name: str, body_size: float, budget: _Budget) -> tuple[np.ndarray, np.ndarray]:
    """``(params, xy)``: the accepted panels ``[u0, u1]`` (m, 2) in parameter order and their
    node positions (m, DEGREE + 1, 2)."""
    lo, hi = gmsh.model.getParametrizationBounds(1, ent)
    a, b = float(lo[0]), float(hi[0])
    if not (np.isfinite(a) and np.isfinite(b) and b > a):
        raise SampleError(f"curve {ent} of '{name}' has no parameter range gmsh can evaluate")
    todo, done = [(a, b, 0)], []
    while todo:
        u0, u1, depth = todo.pop()
        budget.take(2 * DEGREE + 1, name)
        mid, half = 0.5 * (u0 + u1), 0.5 * (u1 - u0)
        p = _positions(gmsh, ent, np.concatenate([mid + half * NODES, mid + half * TESTS]))
        if np.max(np.abs(p[:, 2])) > 1e-12 * max(body_size, float(np.max(np.abs(p[:, :2])))):
            raise SampleError(f"curve {ent} of '{name}' leaves the plane z = 0")
        nodes, tests = p[:DEGREE + 1, :2], p[DEGREE + 1:, :2]
        coef = np.polynomial.chebyshev.chebfit(NODES, nodes, DEGREE)
        err = float(np.max(np.abs(np.polynomial.chebyshev.chebval(TESTS, coef).T - tests)))
        if err <= tolerance(body_size, float(np.max(np.abs(p[:, :2])))):
            done.append((u0, u1, nodes))
            continue
        if depth >= MAX_DEPTH:
            x, y = nodes[DEGREE // 2]
            raise SampleError(f"the curve '{name}' is not smooth near ({x:.6g}, {y:.6g}) (curve {ent}): a corner or "
                              "a cusp; the obstacle must have a continuous tangent")
        todo += [(mid, u1, depth + 1), (u0, mid, depth + 1)]
    done.sort(key=lambda d: d[0])
    return np.array([[d[0], d[1]] for d in done]), np.array([d[2] for d in done])


def bounding_curves(gmsh, free: dict) -> dict[str, list[int]]:
    """The other physical curves (they bound or lie in a surface): name -> entity tags. A body's
    curve may face the body as a deformable obstacle (``obstacle: {type: body}``)."""
    out = {}
    for dim, tag in gmsh.model.getPhysicalGroups(1):
        name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
        ents = [int(e) for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)]
        if ents and name not in free:
            out[name] = ents
    return out


def sample_curves(gmsh, body_size: float, is_geo: bool) -> tuple[tuple[dict, dict], dict]:
    """``((free, bounding), arrays)``: the samples of every free physical curve (possible rigid
    obstacles) and of every other physical curve (possible contact curves of an obstacle body),
    each with its own budget of :data:`MAX_SAMPLES`. ``free[name] = {"entities": [...], "panels":
    [first, end), "error": None or a one-line reason}`` (``bounding`` alike), ``arrays["curve_params"]``
    (m, 2), ``arrays["curve_xy"]`` (m, DEGREE + 1, 2), ``arrays["curve_entity"]`` (m,)."""
    params, xys, ents = [], [], []
    free = free_curves(gmsh)
    infos, count = [], 0                     # count: the panels sampled so far
    for group in (free, bounding_curves(gmsh, free)):
        info, budget = {}, _Budget(MAX_SAMPLES)
        for name, tags in group.items():
            entry = {"entities": tags, "panels": [count, count], "error": None}
            info[name] = entry
            if not is_geo:
                entry["error"] = (f"the physical curve '{name}' of a .msh file has only its mesh (straight segments, "
                                  "a corner at every node), not a smooth geometry: give the .geo file")
                continue
            try:
                got = [sample_entity(gmsh, e, name, body_size, budget) for e in tags]
            except SampleError as err:
                entry["error"] = str(err)
                continue
            first = count
            for e, (pr, xy) in zip(tags, got):
                params.append(pr)
                xys.append(xy)
                ents.append(np.full(len(pr), e, dtype=np.int64))
                count += len(pr)
            entry["panels"] = [first, count]
        infos.append(info)
    arrays = {"curve_params": np.concatenate(params) if params else np.zeros((0, 2)),
              "curve_xy": np.concatenate(xys) if xys else np.zeros((0, DEGREE + 1, 2)),
              "curve_entity": np.concatenate(ents) if ents else np.zeros(0, dtype=np.int64)}
    return (infos[0], infos[1]), arrays


def remove_curves(gmsh, curves: dict) -> None:
    """Take the free physical curves out of the model (their group, entities and end points not
    used by the body) before it is meshed: their elements and nodes are not the body's."""
    tags = {(1, t) for _, t in gmsh.model.getPhysicalGroups(1)
            if (gmsh.model.getPhysicalName(1, t) or str(t)) in curves}
    if not tags:
        return
    gmsh.model.removePhysicalGroups(sorted(tags))
    gmsh.model.removeEntities([(1, e) for ents in curves.values() for e in ents], recursive=True)
