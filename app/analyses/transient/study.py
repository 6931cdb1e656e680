"""The scene's ``transient`` section: the dynamics from its chosen states, a dt study each.

At each chosen state (``transient.states``, the selectors of ``outputs.states``) with MCEIP-lambda^2
solutions at the dynamics' ``mu``, the fastest one's mode starts the run (``u0 + eps v``, velocity
``eps lambda v``) and the measured growth rate is compared with ``lambda`` at every step of the
dt study; at a state without one (``predicted_rate`` null) its mode at ``mode_mu`` (when given)
or a static push of the slip nodes the way friction lets them slide starts it, at rest, and the
run shows whether anything grows. MPI
collective (the matrices gathered on rank 0, which integrates; the records broadcast).
"""
from __future__ import annotations

import math

import numpy as np

from app.analyses.transient.engine import STATUS_CODE, simulate
from app.analyses.transient.mode import MAX_DENSE, contact_operator, divergence_mode

#: points of each run's amplitude kept in results.json (for the plots)
SERIES_POINTS = 400


def run_transients(scene, system, states, comm) -> list[dict] | None:
    """The records of results.json ``transient`` (None when the scene has no such section)."""
    cfg = scene.transient
    if cfg is None:
        return None
    from app.analyses.pencils.state import sequential_km
    from app.io.select import select_states
    pair = sequential_km(system)                                         # MPI collective
    chosen, _ = select_states(states, cfg.states)
    by_index = {s.index: s for s in states}
    mu = cfg.mu if cfg.mu is not None else scene.lambda2_mu
    with_mode = [i for i in chosen if _lambda2_solutions(by_index[i], mu)]
    # the modes at mode_mu of the states with none at mu (MCEIP-lambda^2 again; MPI collective)
    starts = ({i: _mode_at(system, scene, by_index[i], cfg.mode_mu) for i in chosen if i not in with_mode}
              if cfg.mode_mu is not None else {})
    records = None
    if comm.rank == 0:
        K, M = (dense_copy(X) for X in pair) if system.n_dofs <= MAX_DENSE else (None, None)
        done = {i: _one(scene, system, K, M, by_index[i]) for i in with_mode}
        # a state with no divergence mode runs as long as the states with one (unless t_end is given)
        lengths = [r["t_end"] for r in done.values() if r.get("t_end")]
        t_end = max(lengths) if lengths and cfg.t_end is None else None
        done.update({i: _one(scene, system, K, M, by_index[i], t_end=t_end, start=starts.get(i))
                     for i in chosen if i not in done})
        records = [done[i] for i in chosen]
    return comm.bcast(records, root=0)                                   # MPI collective


def _lambda2_solutions(st, mu: float) -> list:
    """MCEIP-lambda^2's solutions with lambda^2 > 0 at the state, if it was solved at ``mu``."""
    a = st.analyses.mceip_lambda2
    if a is None or not a.answered or (a.mu is not None and abs(float(a.mu) - mu) > 1e-12 * max(1.0, mu)):
        return []
    return [s for s in a.solutions if s.value > 0]


def dense_copy(X) -> np.ndarray:
    """A sequential PETSc matrix as a dense numpy array (a copy: the system's own matrix stays as it is)."""
    from app.linalg import to_scipy
    return to_scipy(X).toarray()


def _mode_at(system, scene, st, mu: float) -> tuple[float, list[str]] | None:
    """``(lambda^2, pattern)`` of MCEIP-lambda^2's largest solution at ``mu`` on the state's
    classification (MPI collective), None when it has none."""
    from app.analyses.runner import analyse_state
    from app.loading.classify import Classification
    cls = Classification(tuple(n.status for n in st.nodes), tuple(int(n.sign) for n in st.nodes))
    out = analyse_state(system, cls, scene.model_copy(update={"analyses": ["mceip_lambda2"], "mceip_lambda2_mu": mu}))
    sols = [s for s in (getattr(out.get("mceip_lambda2"), "solutions", None) or []) if s.value > 0]
    if not sols:
        return None
    best = max(sols, key=lambda s: s.value)
    return float(best.value), list(best.pattern)


def _one(scene, system, K, M, st, t_end: float | None = None, start: tuple | None = None) -> dict:
    cfg = scene.transient
    mu = cfg.mu if cfg.mu is not None else scene.lambda2_mu
    rec: dict = {"state": st.index, "mu": mu, "eps": cfg.eps, "predicted_rate": None, "lambda2": None}
    if K is None:
        rec["skipped"] = (f"the dynamics are dense so far: {system.n_dofs} DOFs, above {MAX_DENSE} "
                          "(docs/limitations.md)")
        return rec
    status = [n.status for n in st.nodes]
    if "zero" in status:
        rec["skipped"] = "a state with zero-reaction nodes: their status in the mode is not determined here"
        return rec
    signs = [n.sign for n in st.nodes]
    uT = np.array([n.u_T for n in st.nodes])
    uN = np.array([n.u_N for n in st.nodes])
    # the state held on the Coulomb cone of mu: its slip nodes' r_T = S mu |r_N|
    r0 = np.array([[n.sign * mu * abs(n.r_N) if n.status == "slip" else n.r_T, n.r_N] for n in st.nodes]).ravel()
    sols = _lambda2_solutions(st, mu)        # none when MCEIP-lambda^2 was solved at another mu
    if sols:
        sol = max(sols, key=lambda s: s.value)
        mode = divergence_mode(K, M, system.nodes, status, signs, sol.pattern, mu, float(sol.value))
        lam = math.sqrt(float(sol.value))
        v, rate = mode.v, lam
        T = math.log(cfg.growth) / lam
        dts = [f / lam for f in cfg.steps]
        rec.update(predicted_rate=lam, lambda2=float(sol.value), mode_singular=mode.singular,
                   start="the divergence mode (largest lambda^2), velocity eps lambda v")
    elif start is not None:              # the same classification's mode above its onset, at rest
        lam2, pattern = start
        mode = divergence_mode(K, M, system.nodes, status, signs, pattern, cfg.mode_mu, lam2)
        v, rate = mode.v, None
        lam_start = math.sqrt(lam2)
        T = t_end or cfg.t_end or math.log(cfg.growth) / lam_start
        dts = [f / lam_start for f in cfg.steps]
        rec.update(start=f"its divergence mode at mu = {cfg.mode_mu:g} (lambda^2 = {lam2:.6g}), at rest",
                   mode_singular=mode.singular)
    else:
        v, rate = _static_push(K, system.nodes, status, signs), None
        omega = _lowest_frequency(K, M)
        T = t_end or cfg.t_end or 20.0 * 2.0 * math.pi / omega
        dts = [f / omega for f in cfg.steps]
        rec.update(start="a static push of the slip nodes the way friction lets them slide, at rest",
                   lowest_frequency=omega)
    rec["t_end"] = T
    runs = []
    for h in dts:
        tr = simulate(K, M, system.nodes, uT, uN, r0, mu, v, rate, cfg.eps, h, T)
        E, L = tr.extra["energy"], tr.extra["total_energy"]
        changes = int(np.count_nonzero(np.any(np.diff(tr.status, axis=0) != 0, axis=1))) if len(tr.status) > 1 else 0
        last = np.bincount(tr.status[-1], minlength=3) if len(tr.status) else np.zeros(3, int)
        keep = np.unique(np.linspace(0, len(tr.t) - 1, min(SERIES_POINTS, len(tr.t))).astype(int))
        runs.append({"dt": h, "steps": len(tr.t) - 1, "measured_rate": tr.measured_rate,
                     "relative_error": (None if tr.measured_rate is None or rate is None
                                        else abs(tr.measured_rate / rate - 1.0)),
                     "energy_max_ratio": float(E.max() / E[0]) if E[0] > 0 else None,
                     "amplitude_max_ratio": float(np.abs(tr.amplitude).max() / cfg.eps),
                     "total_energy_change": float(L[-1] - L[0]), "total_energy_rise": float(L.max() - L[0]),
                     "final_status": {k: int(last[c]) for k, c in STATUS_CODE.items()},
                     "status_changes": changes, "violation": tr.violation,
                     "series": {"t": tr.t[keep].tolist(), "amplitude": tr.amplitude[keep].tolist(),
                                # each kept time's node statuses (0 free, 1 stick, 2 slip; the start's: the state's)
                                "status": [[STATUS_CODE.get(x, 1) for x in status] if j == 0
                                           else tr.status[j - 1].tolist() for j in keep]}})
    rec["runs"] = runs
    rec["measured_rate"] = runs[-1]["measured_rate"]
    errors = [r["relative_error"] for r in runs]
    if rate is not None and len(runs) > 1 and all(e is not None and e > 0 for e in errors[-2:]):
        rec["observed_order"] = math.log(errors[-2] / errors[-1]) / math.log(dts[-2] / dts[-1])
    return rec


def _static_push(K: np.ndarray, nodes, status, signs) -> np.ndarray:
    """The static response to a unit tangential force at every slip node in the direction it may
    slide (``-S``), contacts held: a smooth start for a state with no divergence mode."""
    n = K.shape[0]
    B = contact_operator(nodes, n)
    f = np.zeros(n)
    for i, st in enumerate(status):
        if st == "slip":
            f += -signs[i] * B[2 * i]
    v = np.linalg.solve(K, f)
    return v / max(np.abs(v).max(), 1e-300)


def _lowest_frequency(K: np.ndarray, M: np.ndarray) -> float:
    """The lowest circular frequency of ``(K, M)`` (the contacts free), 1/time."""
    import scipy.linalg
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True, subset_by_index=[0, 0])[0]
    return math.sqrt(max(float(w2), 1e-300))
