"""MCEIP-mu on a curved obstacle: the quadratic complementarity eigenproblem (docs/method.md section 8).

On a curved obstacle the condensed pencil of the transition problem is quadratic in mu,

    A(mu) x = y,   A(mu) = A0 + mu A1 + mu^2 A2,   mu >= 0,   0 <= x ⊥ y >= 0,   x != 0,

with ``A2 = G = diag(kappa_i P_i)`` on the slip nodes. Solutions are found by enumeration of the
``2^s - 1`` supports ``J`` (the slip nodes that keep slipping in the mode): each support is the
quadratic eigenproblem ``A(mu)[J, J] x_J = 0``, solved through its first companion
linearisation

    [[0, I], [-A0_JJ, -A1_JJ]] z = mu [[I, 0], [0, A2_JJ]] z,    z = (x_J, mu x_J),

(QZ, scipy.linalg.eig: a singular ``A2`` gives infinite eigenvalues, which are dropped), and
each real ``mu >= 0`` with a null vector ``x_J > 0`` and ``y = A(mu)[J^c, J] x_J >= 0`` is a
solution (the sign checks (26)). With ``A2 = 0`` this is the flat enumeration (24)-(26).

What this proves: nothing, in the sense of :mod:`app.analyses.mceip_mu`. The enumeration is
exhaustive over supports, but each eigenproblem and each sign check is decided in floating
point, so the results are reported as *found by exhaustive enumeration, not proven*
(``certified: false``); margins below ``RESOLVE_TOL`` are flagged ``ill_conditioned``. Refused
above ``max_slip`` slip nodes (``settings.enumerate_max_slip``).
"""
from __future__ import annotations

import itertools
import time

import numpy as np
import scipy.linalg

from app.analyses.enumerate import RESIDUAL_TOL, RESOLVE_TOL, TooManySlipNodes, pencil_scale


def quadratic_eigenvalues(a0: np.ndarray, a1: np.ndarray, a2: np.ndarray) -> np.ndarray:
    """Finite eigenvalues of ``(a0 + mu a1 + mu^2 a2) x = 0`` (complex array)."""
    k = a0.shape[0]
    Z, I = np.zeros((k, k)), np.eye(k)
    L = np.block([[Z, I], [-a0, -a1]])
    B = np.block([[I, Z], [Z, a2]])
    w = scipy.linalg.eig(L, B, right=False)
    return w[np.isfinite(w)]


def enumerate_quadratic(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, max_slip: int,
                        mu_max: float = np.inf) -> list[dict]:
    """Every solution of the quadratic MCEIP-mu with ``0 <= mu <= mu_max``, by supports.

    Returns dicts with ``value``, ``x_Ts`` (sum 1), ``pattern``, ``residual`` (smallest singular
    value of ``A(mu)[J, J]`` relative to ``||a0|| + mu ||a1|| + mu^2 ||a2||``), ``complementarity``,
    ``min_x_Ts``, ``min_y_Ts``, ``margin_y_stick`` and ``ill_conditioned``; sorted by value.
    """
    s = A0.shape[0]
    if s > max_slip:
        raise TooManySlipNodes(f"{s} slip nodes: enumeration of the 2^{s} supports of the quadratic MCEIP-mu "
                               f"refused (settings.enumerate_max_slip = {max_slip})")
    sc = pencil_scale(A0)
    a0, a1, a2 = A0 / sc, A1 / sc, A2 / sc
    out: list[dict] = []
    for k in range(1, s + 1):
        for J in itertools.combinations(range(s), k):
            J = np.array(J)
            b0, b1, b2 = a0[np.ix_(J, J)], a1[np.ix_(J, J)], a2[np.ix_(J, J)]
            n0, n1, n2 = (np.linalg.norm(b, 2) for b in (b0, b1, b2))
            for w in quadratic_eigenvalues(b0, b1, b2):
                mu = float(w.real)
                if abs(w.imag) > 1e-6 * max(1.0, abs(mu)) or mu < -1e-12 or mu > mu_max * (1 + 1e-12):
                    continue
                mu = max(mu, 0.0)
                B = b0 + mu * b1 + mu * mu * b2
                _, sv, Vh = np.linalg.svd(B)
                if sv[-1] > RESIDUAL_TOL * max(n0 + mu * n1 + mu * mu * n2, 1e-300):
                    continue
                v = Vh[-1]
                if v.sum() < 0:
                    v = -v
                mx = float(np.min(v) / max(np.max(np.abs(v)), 1e-300))
                if mx <= 0:
                    continue
                x = np.zeros(s)
                x[J] = v / v.sum()
                y = (a0 + mu * a1 + mu * mu * a2) @ x
                sup = np.zeros(s, dtype=bool)
                sup[J] = True
                stick = y[~sup]
                my = float(np.min(stick)) if len(stick) else np.inf
                if my < -RESOLVE_TOL:
                    continue
                if any(abs(d["value"] - mu) <= 1e-10 * max(1.0, mu) and d["_support"] == tuple(J) for d in out):
                    continue        # a double eigenvalue: one solution
                out.append({"value": mu, "x_Ts": [float(t) for t in x],
                            "pattern": ["slip" if b else "stick" for b in sup],
                            "residual": float(sv[-1] / max(n0 + mu * n1 + mu * mu * n2, 1e-300)),
                            "complementarity": float(np.max(np.abs(x * y))),
                            "min_x_Ts": mx, "min_y_Ts": float(np.min(y)),
                            "margin_y_stick": my if np.isfinite(my) else None,
                            "ill_conditioned": bool(mx < RESOLVE_TOL or my < RESOLVE_TOL),
                            "_support": tuple(J)})
    for d in out:
        del d["_support"]
    return sorted(out, key=lambda d: (d["value"], d["pattern"]))


def quadratic_mu_result(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, cap: float, max_slip: int) -> dict:
    """The ``mceip_mu`` entry of results.json for a curved obstacle: the solutions found by the
    exhaustive floating-point enumeration, ``certified: false`` (found, not proven)."""
    from app.analyses.certify import certificate       # the certificate record's format only
    t0 = time.perf_counter()
    s = A0.shape[0]
    how = "quadratic MCEIP-mu: every support enumerated, companion linearisation + QZ, sign checks (26) in floating point"
    try:
        sols = enumerate_quadratic(A0, A1, A2, max_slip)
    except TooManySlipNodes as err:
        return {"solutions": [], "result": f"not searched: {err}", "certified": False,
                "onset": {"proven": False, "status": "not searched", "value": None, "enclosure": None},
                "complete": {"proven": False, "status": "not searched", "interval": [0.0, 0.0], "count": None},
                "certificate": certificate("none", (0.0, 0.0), "not attempted", 0.0),
                "search": {"method": how, "complete": False, "note": str(err)}, "quadratic": True}
    for d in sols:
        d.update(certified=False, found_by=["exhaustive enumeration of the quadratic pattern problems"],
                 found_count=1, iterations=0)
    first = sols[0]["value"] if sols else None
    result = ((f"{len(sols)} solution(s) found, smallest mu = {first:.10g}" if sols else "no solution found")
              + " (found by exhaustive floating-point enumeration of the quadratic pattern problems, not proven)")
    seconds = time.perf_counter() - t0
    return {"solutions": sols, "result": result, "certified": False,
            "onset": {"proven": False, "status": "found, not proven", "value": first, "enclosure": None},
            "complete": {"proven": False, "status": "found, not proven", "interval": [0.0, 0.0], "count": None},
            "certificate": certificate("none (floating-point enumeration)", (0.0, 0.0),
                                       "not proven: exhaustive floating-point enumeration of the 2^s supports",
                                       seconds, {"s": s, "cap": float(cap), "solutions": len(sols)}),
            "search": {"method": how, "attempts": 2 ** s - 1, "seconds": round(seconds, 4), "found": len(sols),
                       "intervals": ["[0, inf)"], "complete": False,
                       "note": "every support enumerated; decided in floating point (not a proof)"},
            "quadratic": True}
