"""Nonsmooth dynamics from an equilibrium state: implicit time stepping with the contact solved
exactly at every step.

The deviation ``U = u - u0`` from the state obeys ``M U'' + K U = B^T (r - r0)`` (the applied
loads held: ``K u0 = f + B^T r0``). Each step of length ``h`` is Moreau's catching-up scheme,
backward Euler on positions and velocities,

    A U_{k+1} = M (U_k + h U'_k) / h^2 + B^T (r_{k+1} - r0),     A = K + M / h^2,
    U'_{k+1} = (U_{k+1} - U_k) / h,

with the contact reactions ``r_{k+1}`` at the end of the step satisfying Signorini's condition
and Coulomb's law on the step's slip increment, the time-discrete laws (1)-(2) the quasi-static
path satisfies (app/loading/contact.py). On the contact displacements (paper axes) the step is
exactly a quasi-static contact increment: ``u_c = u_c^0 + W_A r`` with the dynamic flexibility
``W_A = B A^-1 B^T`` and ``u_c^0`` the contact displacement the step gives with no reaction, so
the same solver (PETSc SNES VI, checked against the conditions) solves it exactly: an impact is
inelastic, a node stays on the obstacle or leaves it, a sliding node carries
``r_T = -mu p sign(d)``. The scheme is first order and dissipative (its energy never grows by
itself, so a growth it shows is the system's); on ``a'' = lambda^2 a`` it grows at
``-ln(1 - h lambda) / h = lambda (1 + h lambda / 2 + ...)``. The trapezoidal rule (second order,
no damping) was tried and rejected: with the contact laws at the end of each step it gained
energy at status changes and blew up below the onset at small steps (docs/validation.md).

Dense (the systems of the tests and the paper's block on its meshes): ``A^-1 B^T`` is computed
once per step length.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from app.analyses.transient.mode import contact_operator
from app.loading.contact import FrictionalContact

STATUS_CODE = {"free": 0, "stick": 1, "slip": 2}


@dataclass
class Transient:
    """A simulated motion: ``t`` (the times), ``amplitude`` (the projection of ``U`` on the mode,
    ``a = v^T M U / v^T M v``), the contact ``status`` of every node at every step (0 free,
    1 stick, 2 slip), the fitted growth rate ``measured_rate`` [1/time] over the last
    ``fit_fraction`` of the run (None when the amplitude does not grow), the ``predicted_rate``
    ``sqrt(lambda^2)`` (None without a divergence mode), the step ``dt``, the largest relative
    violation of the contact laws over the steps; ``extra["energy"]``: the deviation's kinetic
    plus elastic energy ``(U'^T M U' + U^T K U) / 2`` at every step; ``extra["total_energy"]``:
    that plus the work the held loads did, ``+ r0^T B U`` (the total mechanical energy's change:
    the contact laws make it non-increasing, friction and impacts dissipate)."""

    t: np.ndarray
    amplitude: np.ndarray
    status: np.ndarray
    dt: float
    predicted_rate: float | None
    measured_rate: float | None
    violation: float
    extra: dict = field(default_factory=dict)


def growth_rate(t: np.ndarray, a: np.ndarray, fit_fraction: float = 0.5) -> float | None:
    """The least-squares slope of ``log |a|`` against ``t`` over the last ``fit_fraction`` of the
    run; None when the amplitude passes through zero or does not grow there."""
    k = int(len(t) * (1.0 - fit_fraction))
    tt, aa = t[k:], np.abs(a[k:])
    if len(tt) < 3 or np.any(aa <= 0):
        return None
    slope = float(np.polyfit(tt, np.log(aa), 1)[0])
    return slope if slope > 0 else None


def simulate(K: np.ndarray, M: np.ndarray, nodes, state_u_T: np.ndarray, state_u_N: np.ndarray,
             state_r: np.ndarray, mu: float, v: np.ndarray, rate: float | None, eps: float, dt: float,
             t_end: float, fit_fraction: float = 0.5) -> Transient:
    """The motion from the state (contact displacements ``state_u_T``, ``state_u_N`` and reactions
    ``state_r`` in paper axes, T_0, N_0, ...) started at ``u0 + eps v`` with velocity
    ``eps rate v`` (``rate``: the predicted ``lambda``; 0 or None: at rest), integrated with
    steps ``dt`` up to ``t_end``."""
    n, nc = K.shape[0], len(nodes)
    B = contact_operator(nodes, n)
    h = float(dt)
    A = K + M / h**2
    factor = scipy.linalg.cho_factor(A)            # SPD: K SPD (the body held), M SPD
    AinvBt = scipy.linalg.cho_solve(factor, B.T)
    W = B @ AinvBt
    lam = float(rate or 0.0)
    U = eps * v
    Ud = eps * lam * v
    r0 = np.asarray(state_r, dtype=float)
    u_c0 = np.empty(2 * nc)
    u_c0[0::2], u_c0[1::2] = state_u_T, state_u_N
    u_T_prev = state_u_T + (B @ U)[0::2]
    g_prev = np.maximum(-np.asarray(state_u_N, dtype=float), 0.0)     # the mode keeps the contacts closed
    steps = int(np.ceil(t_end / h))
    Mv = M @ v
    vMv = float(v @ Mv)
    times, amps, stats = [0.0], [float(Mv @ U) / vMv], []
    energy = [0.5 * float(Ud @ M @ Ud) + 0.5 * float(U @ K @ U)]
    total = [energy[0] + float(r0 @ (B @ U))]
    worst = 0.0
    with FrictionalContact(np.linalg.inv(W), mu) as contact:
        for k in range(steps):
            rhs = M @ ((U + h * Ud) / h**2) - B.T @ r0
            U_free = scipy.linalg.cho_solve(factor, rhs)
            # started from no slip: the previous step's slip increments, of the size of the
            # perturbation, can sit below the solver's force tolerance and stop it at once
            inc = contact.solve(u_c0 + B @ U_free, u_T_prev, g_prev, None)
            r = np.empty(2 * nc)
            r[0::2], r[1::2] = inc.r_T, inc.r_N
            U_new = U_free + AinvBt @ r
            Ud, U = (U_new - U) / h, U_new
            energy.append(0.5 * float(Ud @ M @ Ud) + 0.5 * float(U @ K @ U))
            total.append(energy[-1] + float(r0 @ (B @ U)))
            u_T_prev, g_prev = inc.u_T, -inc.u_N
            worst = max(worst, inc.violation)
            times.append((k + 1) * h)
            amps.append(float(Mv @ U) / vMv)
            stats.append(_statuses(inc, mu))
    t, a = np.array(times), np.array(amps)
    return Transient(t=t, amplitude=a, status=np.array(stats, dtype=np.int8), dt=h,
                     predicted_rate=None if not lam else lam, measured_rate=growth_rate(t, a, fit_fraction),
                     violation=worst, extra={"energy": np.array(energy), "total_energy": np.array(total)})


def _statuses(inc, mu: float) -> list[int]:
    """Each node's status after a step: free (no pressure), slip (on the cone and sliding), stick."""
    p = -inc.r_N
    scale = max(float(np.abs(inc.r_N).max(initial=0.0)), 1e-300)
    out = []
    for pi, rT, d in zip(p, inc.r_T, inc.slip_increment):
        if pi <= 1e-12 * scale:
            out.append(STATUS_CODE["free"])
        elif abs(d) > 0 and abs(abs(rT) - mu * pi) <= 1e-9 * scale:
            out.append(STATUS_CODE["slip"])
        else:
            out.append(STATUS_CODE["stick"])
    return out
