"""Small dense LPs for the prover's Farkas vectors: ``min c^T z`` subject to ``A_ub z <= 0`` and
bounds, by HiGHS (through SciPy).

The prover solves thousands of LPs of 10-40 variables per pencil; ``scipy.optimize.linprog``
spends about two thirds of each call validating its input and building a sparse matrix. This
module calls SciPy's HiGHS wrapper directly (the same solver, options and result fields
``linprog(method="highs")`` uses in the SciPy 1.10 that Debian bookworm ships), and falls back to
``linprog`` if that private entry point is missing or changes. Nothing here is trusted: every
vector the LP returns is re-checked with rigorous bounds by
:func:`app.analyses.mceip_mu.kernel.closing.farkas_closes`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

try:                                    # SciPy's private HiGHS entry point (fast path)
    from scipy.optimize._highs import _highs_constants as _hc
    from scipy.optimize._highs._highs_wrapper import _highs_wrapper
except ImportError:                     # pragma: no cover - other SciPy layouts use linprog
    _highs_wrapper = None

_INF = 1e20                             # HiGHS' infinity, as linprog passes it


@dataclass
class LPResult:
    """The answer of :func:`solve`: whether an optimal solution was found, the solution and the duals
    (marginals) of the inequality rows, None where there is none."""

    ok: bool                            # an optimal solution was found
    x: np.ndarray | None                # the solution
    marginals: np.ndarray | None        # duals of the inequality rows (linprog's sign convention)


def solve(c: np.ndarray, A_ub: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> LPResult:
    """``min c^T z``, ``A_ub z <= 0``, ``lb <= z <= ub`` (``+-inf`` allowed in the bounds)."""
    if _highs_wrapper is not None:
        try:
            return _solve_highs(c, A_ub, lb, ub)
        except (TypeError, KeyError, AttributeError):      # pragma: no cover - a changed wrapper
            pass
    r = scipy.optimize.linprog(c, A_ub=A_ub, b_ub=np.zeros(A_ub.shape[0]), bounds=list(zip(lb, ub)),
                               method="highs")
    if r.status != 0 or r.x is None:
        return LPResult(False, None, None)
    return LPResult(True, np.asarray(r.x), np.asarray(r.ineqlin.marginals, dtype=float))


def _solve_highs(c, A_ub, lb, ub) -> LPResult:
    m, n = A_ub.shape
    mask = A_ub != 0
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=0))]).astype(np.int32)
    rows = np.nonzero(mask.T)                                # column-major order of the nonzeros
    indices = rows[1].astype(np.int32)
    data = np.ascontiguousarray(A_ub.T[rows], dtype=np.float64)
    lhs = np.full(m, -_INF)
    rhs = np.zeros(m)
    options = {"presolve": True, "sense": _hc.HIGHS_OBJECTIVE_SENSE_MINIMIZE, "solver": None,
               "time_limit": None, "highs_debug_level": _hc.MESSAGE_LEVEL_NONE, "log_to_console": False,
               "output_flag": False, "simplex_strategy": _hc.HIGHS_SIMPLEX_STRATEGY_DUAL}
    res = _highs_wrapper(np.ascontiguousarray(c, dtype=np.float64), indptr, indices, data, lhs, rhs,
                         np.clip(np.asarray(lb, dtype=np.float64), -_INF, _INF),
                         np.clip(np.asarray(ub, dtype=np.float64), -_INF, _INF),
                         np.empty(0, dtype=np.uint8), options)
    if res.get("status") != _hc.MODEL_STATUS_OPTIMAL or "x" not in res:
        return LPResult(False, None, None)
    lam = np.asarray(res["lambda"], dtype=float)[:m] if "lambda" in res else None
    return LPResult(True, np.asarray(res["x"], dtype=float), lam)
