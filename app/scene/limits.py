"""Resource pre-flight: estimate a study's size before anything heavy runs, refuse what is too big.

The estimates are arithmetic on the scene (no mesh, no PETSc), so a scene asking for ten
billion load states or a 4096 x 4096 mesh is refused within milliseconds, with one line naming
the key to change. The limits are the scene's ``settings.limits`` (README, "Resource limits").
"""
from __future__ import annotations

import logging
import os
import resource
from dataclasses import dataclass

from app.scene.schema import Scene, SceneError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Estimate:
    """Sizes of one study (upper bounds for the number of states: gross sliding may end it early)."""

    states: int
    dofs: int
    contact_nodes: int
    memory_bytes: int

    def describe(self) -> str:
        """The estimate in one line for the log: states, DOFs, contact nodes and memory in GiB."""
        return (f"pre-flight: at most {self.states} load states, {self.dofs} DOFs, {self.contact_nodes} contact "
                f"nodes, memory estimate {self.memory_bytes / 2**30:.2g} GiB")


def estimate(scene: Scene, nx: int | float | None = None) -> Estimate:
    """Sizes and a rough memory estimate of ``scene`` (``nx``: a refinement level, the block's
    override of ``system.nx``, ny scaled, or a Gmsh body's ``system.mesh_size_factor``)."""
    cfg = scene.system
    if not hasattr(cfg, "mesh_sizes"):     # a system type sized by its files, or not at all (app/systems/)
        states = cfg.load_states()[0] if hasattr(cfg, "load_states") else 1
        if not hasattr(cfg, "file_sizes"):
            return Estimate(states=states, dofs=4, contact_nodes=2, memory_bytes=200 * 2**20 + 1500 * 2 * states)
        if nx is not None and hasattr(cfg, "mesh_size_factor"):       # a refinement level: the .geo meshed at it
            cfg = cfg.model_copy(update={"mesh_size_factor": float(nx)})
        dofs, contact, _ = cfg.file_sizes()          # from the mesh or matrix file read at validation
        return Estimate(states=states, dofs=dofs, contact_nodes=contact,
                        memory_bytes=_memory(scene, dofs, contact, states, getattr(cfg, "degree", 1)))
    if nx is not None:
        cfg = cfg.refined(nx)
    ld = scene.loading
    steps = ld.tangential_max / ld.tangential_step
    states = ld.normal_steps + (int(steps + 1e-9) if steps < 1e18 else 10**18)
    dofs, contact = cfg.mesh_sizes()
    return Estimate(states=states, dofs=dofs, contact_nodes=contact,
                    memory_bytes=_memory(scene, dofs, contact, states, cfg.degree))


def _memory(scene: Scene, dofs: int, contact: int, states: int, degree: int) -> int:
    """The memory estimate [bytes] of a study of these sizes: the libraries; the sparse work per
    DOF; the W build's chunk; the contact flexibility (2c)^2 dense, a few copies; the dense
    reduced pencils up to eig.dense_limit; about 1.5 kB per node and state in the results."""
    return int(BASE_RESIDENT + per_dof_bytes(degree) * dofs + w_build_bytes(dofs, 2 * contact)
               + 4 * 8 * (2 * contact) ** 2 + 6 * 8 * min(dofs, scene.settings.eig.dense_limit) ** 2
               + 1500 * contact * states)


def _size_key(scene: Scene, nx: int | None) -> tuple[str, object]:
    """(key, value) that sets the size of the study, named in the pre-flight's refusals."""
    cfg = scene.system
    if nx is not None and hasattr(cfg, "mesh_size_factor"):
        return "refinement.size_factors", nx
    if hasattr(cfg, "file_sizes"):
        import pathlib
        key = cfg.file_sizes()[2]
        return key, pathlib.Path(getattr(cfg, key.split(".")[-1])).name
    if nx is not None:
        return "refinement.levels", nx
    if cfg.pattern == "unstructured":
        return "system.mesh_size", cfg.mesh_size
    return "system.nx", cfg.nx


#: resident memory of Python, MPI, PETSc, SLEPc, DOLFINx and gmsh before the study's own data
BASE_RESIDENT = 250 * 2**20


def per_dof_bytes(degree: int) -> float:
    """Resident bytes per DOF of the sparse work: mesh, function spaces, K and M, the LU factors
    of K (MUMPS). Fitted to serial peaks of crossed P1 block studies (benchmarks/estimates.py:
    0.27 GiB at 6.4k DOFs, 0.59 at 101k, 0.90 at 206k, ... 2.5 at 1.0M); P2 rows hold about twice
    as many entries, and its factors fill more (scaled, not fitted)."""
    return 2700.0 if degree == 1 else 6000.0


def w_build_bytes(dofs: int, columns: int) -> int:
    """The dense solution chunk of the contact flexibility build and MUMPS's copy of it
    (app/loading/flexibility.py)."""
    from app.loading.flexibility import chunk_columns
    return 2 * 8 * dofs * chunk_columns(dofs, columns)


def _physical_memory() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def memory_limit(scene: Scene) -> tuple[float, str]:
    """(bytes, how it was set): ``settings.limits.max_memory_gb``, else 80 % of the machine's RAM."""
    return scene.settings.limits.memory_cap()


#: address space mapped before any work: Python, MPI, PETSc, SLEPc, DOLFINx and their libraries
#: (a 10 x 5 block study peaks at about 0.85 GiB of virtual memory, 0.2 GiB resident)
BASE_ADDRESS_SPACE = 1 << 30


def address_space_limit() -> int | None:
    """The process's address-space limit (``ulimit -v``) in bytes, or None when unlimited."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def check(scene: Scene, source: str = "scene") -> Estimate:
    """Estimate ``scene`` and raise :class:`SceneError` (one line naming the key) above a limit."""
    lim = scene.settings.limits
    levels = scene.refinement.steps() if scene.refinement is not None else [None]
    worst = None
    for nx in levels:
        est = estimate(scene, nx)
        if est.states > lim.max_states and hasattr(scene.system, "load_states"):
            key = scene.system.load_states()[1]
            raise SceneError(f"{source}: {key}: {est.states} load states exceed settings.limits.max_states = "
                             f"{lim.max_states}; use fewer steps or raise the limit")
        if est.states > lim.max_states:
            ld = scene.loading
            raise SceneError(f"{source}: loading.tangential_step = {ld.tangential_step}: {est.states} load states "
                             f"(normal_steps + tangential_max / tangential_step) exceed "
                             f"settings.limits.max_states = {lim.max_states}; use a larger step or raise the limit")
        if est.dofs > lim.max_dofs:
            key, val = _size_key(scene, nx)
            raise SceneError(f"{source}: {key} = {val}: about {est.dofs} DOFs exceed settings.limits.max_dofs = "
                             f"{lim.max_dofs}; use a coarser mesh or raise the limit")
        if est.contact_nodes > lim.max_contact_nodes:
            key, val = _size_key(scene, nx)
            raise SceneError(f"{source}: {key} = {val}: {est.contact_nodes} contact nodes exceed "
                             f"settings.limits.max_contact_nodes = {lim.max_contact_nodes}")
        if worst is None or est.memory_bytes > worst.memory_bytes:
            worst = est
    cap, how = memory_limit(scene)
    if worst.memory_bytes > cap:
        if worst.states > 10 * worst.contact_nodes and scene.loading is not None:
            key, val = "loading.tangential_step", scene.loading.tangential_step
        elif worst.states > 10 * worst.contact_nodes and hasattr(scene.system, "load_states"):
            key, val = scene.system.load_states()[1], worst.states
        elif scene.refinement is not None:
            key, val = _size_key(scene, scene.refinement.steps()[-1])
        else:
            key, val = _size_key(scene, None)
        raise SceneError(f"{source}: {key} = {val}: memory estimate {worst.memory_bytes / 2**30:.3g} GiB "
                         f"({worst.states} states, {worst.dofs} DOFs, {worst.contact_nodes} contact nodes) exceeds "
                         f"{how}; use a coarser mesh or fewer states, or raise settings.limits.max_memory_gb")
    # Under a small address-space cap, DOLFINx's mesh creation was seen spinning for minutes
    # instead of failing (docs/limitations.md): refuse before the work instead.
    avail = address_space_limit()
    need = worst.memory_bytes + BASE_ADDRESS_SPACE
    if avail is not None and avail < need:
        raise SceneError(f"{source}: the address-space limit (ulimit -v) is {avail / 2**30:.2g} GiB, below the "
                         f"about {need / 2**30:.2g} GiB this study needs (DOLFINx, PETSc and MPI map about "
                         f"{BASE_ADDRESS_SPACE / 2**30:.0f} GiB before any work); raise the limit or run without it")
    return worst


def output_bytes(scene: Scene, est: Estimate) -> int:
    """A rough upper estimate of what the run writes (results.json, steps.csv, fields, pictures)."""
    size = 4096 + est.states * (2000 + 300 * est.contact_nodes)
    outputs = scene.outputs
    if outputs.fields:
        size += est.states * est.dofs * 8 * 4
    if outputs.plots or outputs.report or outputs.screenshots is not None:
        size += 20 * 2**20
    return int(size)


def check_disk(scene: Scene, est: Estimate, folder, shown=None) -> str | None:
    """A one-line problem if the file system holding ``folder`` has clearly too little free space
    (``shown``: the folder named in the message, default ``folder``)."""
    import pathlib
    need = output_bytes(scene, est) + 16 * 2**20
    path = pathlib.Path(folder)
    while not path.exists() and path != path.parent:
        path = path.parent
    try:
        st = os.statvfs(path)
    except OSError:
        return None
    free = st.f_bavail * st.f_frsize
    if free < need:
        return (f"not enough free space for the results in {shown or path}: about {need / 2**20:.0f} MiB needed, "
                f"{free / 2**20:.0f} MiB free")
    return None


#: analyses the time model covers (the others are named as not counted)
TIMED_ANALYSES = ("mceip_mu", "necessary", "sufficient", "mceip_lambda2")


def _classifications(c: float) -> float:
    """Distinct classifications along the block's path with ``c`` = contact nodes / 225 (measured:
    40 at 41 nodes, 68 at 81, 80 at 113, 104 with slip nodes at 225)."""
    return 110.0 * c ** 0.6


def analysis_seconds(scene: Scene, dofs: int, contact_nodes: int) -> dict[str, float]:
    """Seconds of each requested analysis other than MCEIP-mu on the block's path, per
    classification times :func:`_classifications`; fitted to serial runs of the block at 3.2k,
    25k and 101k DOFs (2026-12-06, docs/performance.md).

    - necessary (19) below ``eig.necessary_contact_min_dofs``: SLEPc shift-and-invert and two LDL^T
      inertia counts per matrix on the full-size pencils: 44 ms per classification at 3.2k DOFs,
      0.55 s at 25k, 2.9 s at 101k, as DOFs^1.22; from it on, on the contact DOFs: a few dozen
      partial factorisations shared by the whole path and a root solve per classification:
      4.9 s at 25k (80 classifications), 24.9 s at 101k (104), as 23 s (DOFs / 10^5)^1.2 + 0.02 s per classification;
    - MCEIP-lambda^2: the exact reduction on the contact DOFs, a third of a partial factorisation
      of K + t M per classification (the shared dyadic grid) and dense work on the contact DOFs:
      0.14 s per classification at 101k DOFs (0.031 s at 25k), about proportional to the DOFs;
    - sufficient (17)-(18): nothing when MCEIP-lambda^2 at the same mu runs (it decides the
      condition), else SLEPc on the full pencil, 1.04 s per classification at 25k, as DOFs^1.3;
    - an incompressible material with the mixed element (nu = 1/2): MCEIP-lambda^2 has no bound and
      is searched on the full pencils (SNES VI), 0.34 s per classification at 936 DOFs and 1.33 s
      at 3,671 (the paper's block, 2026-12-06), as DOFs; the sufficient condition always runs."""
    x, c = dofs / 1e5, contact_nodes / 225.0
    n = _classifications(c)
    out = {}
    if "necessary" in scene.analyses:
        if dofs >= scene.settings.eig.necessary_contact_min_dofs:
            out["necessary"] = 23.0 * x ** 1.2 + 0.02 * n
        else:
            out["necessary"] = n * 0.545 * (x / 0.2543) ** 1.22
    system = scene.system
    constraint = (getattr(system, "element", "displacement") == "mixed"
                  and 0.5 in system.poisson_ratios().values())
    if "mceip_lambda2" in scene.analyses:
        out["mceip_lambda2"] = n * (0.36 * dofs / 1e3 if constraint else 0.14 * x)
    if "sufficient" in scene.analyses:
        decided = "mceip_lambda2" in scene.analyses and scene.lambda2_mu == scene.mu and not constraint
        out["sufficient"] = 0.0 if decided else n * 1.04 * (x / 0.2543) ** 1.3
    return out


def time_estimate(scene: Scene, est: Estimate) -> float | None:
    """Seconds a serial run of ``scene`` takes on one idle core of the kind measured: start-up,
    mesh + assembly + factorisation + W, the loading increments, MCEIP-mu at every
    classification and the other requested analyses (:func:`analysis_seconds`). None for a
    system without a mesh-size estimate.

    The MCEIP-mu part is a model fitted to CPU times of the paper's block study (crossed P1,
    ``analyses: [mceip_mu]``) at 6.4k, 25k, 101k, 403k and 1.0M DOFs (benchmarks/estimates.py,
    2-core machine, the other core idle; the stage times as the runs print them); the total is
    within a factor 1.3 of those runs. The enumeration is not counted."""
    if not hasattr(scene.system, "mesh_sizes"):
        return None
    x, c = est.dofs / 1e5, est.contact_nodes / 225.0
    start = 1.5 + 2.8 * x ** 0.8                       # imports, form compilation, writing results
    build = 0.3 + 1.4 * x ** 1.14                      # mesh, K, its LU factors and W = B K^-1 B^T
    increment = 1.12e-3 + 2.67e-3 * c ** 3             # one contact increment: dense 2c x 2c LUs
    # classifications ~ c; most below the onset are proven by the sign argument alone (a few
    # Cholesky factorisations, ~ s^3), the rest searched and proven
    mceip = 0.8 + 1.0 * c + 0.8 * c ** 3 if "mceip_mu" in scene.analyses else 0.0
    others = sum(analysis_seconds(scene, est.dofs, est.contact_nodes).values())
    return start + build + est.states * increment + mceip + others


def describe_time(scene: Scene, est: Estimate) -> str | None:
    """The time estimate as printed by ``validate``, saying what it covers; None without one."""
    t = time_estimate(scene, est)
    if t is None:
        return None
    left = [a for a in scene.analyses if a not in TIMED_ANALYSES]
    size = f"{t:.0f} s" if t < 120 else f"{t / 60:.0f} min"
    return (f"time estimate about {size} on 1 rank of an idle core (a model fitted to measured block "
            f"studies, taking all {est.states} states" + (f"; not counting {', '.join(left)}" if left else "") + ")")
