"""Classification of the contact nodes of an equilibrium state (paper, after eq. (9)).

Every contact node is exactly one of ``free`` (u_N < 0, r_N = 0), ``zero`` (u_N = 0, r_N = 0:
the paper's set Z), ``stick`` (r_N < 0, |r_T| < -mu r_N) or ``slip`` (r_N < 0,
|r_T| = -mu r_N, sign S = sign(r_T)). "Zero" and "equal" are decided with tolerances relative
to the scale of the state's reactions and displacements, so the same physical state in any
consistent unit system classifies identically.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.loading.state import EquilibriumState

FREE, ZERO, STICK, SLIP = "free", "zero", "stick", "slip"


@dataclass(frozen=True)
class Classification:
    """Status and slip sign of every contact node; hashable so analyses can be shared."""

    status: tuple[str, ...]
    signs: tuple[int, ...]

    @property
    def key(self) -> tuple:
        """States with equal keys have identical reduced pencils (10)-(16)."""
        return self.status, tuple(s if st == SLIP else 0 for s, st in zip(self.signs, self.status))

    def indices(self, status: str) -> np.ndarray:
        """Indices of the contact nodes of ``status`` (``free``, ``zero``, ``stick`` or ``slip``),
        ascending."""
        return np.array([i for i, s in enumerate(self.status) if s == status], dtype=np.int64)

    @property
    def slip(self) -> np.ndarray:
        """Indices of the slip nodes, ascending."""
        return self.indices(SLIP)

    @property
    def slip_signs(self) -> np.ndarray:
        """Slip signs ``S`` of the slip nodes (+1 or -1), in the order of :attr:`slip`."""
        return np.array([self.signs[i] for i in self.slip], dtype=float)

    def counts(self) -> dict[str, int]:
        """Number of contact nodes of each status."""
        return {s: self.status.count(s) for s in (FREE, ZERO, STICK, SLIP)}

    def label(self) -> str:
        """The counts in words, ``"12 stick / 4 slip / 3 free"``, with ``" / 1 zero"`` when some node
        is zero."""
        c = self.counts()
        return f"{c[STICK]} stick / {c[SLIP]} slip / {c[FREE]} free" + (f" / {c[ZERO]} zero" if c[ZERO] else "")


def classified(state: EquilibriumState, mu: float, rtol: float = 1e-8) -> Classification:
    """:func:`classify`, made once per state: the loading path's classification of ``state``
    (``state.classified``) when it used the same ``mu`` and ``rtol``, else a new one (kept)."""
    if state.classified is not None and state.classified[:2] == (mu, rtol):
        return state.classified[2]
    cls = classify(state, mu, rtol)
    state.classified = (mu, rtol, cls)
    return cls


def classify(state: EquilibriumState, mu: float, rtol: float = 1e-8) -> Classification:
    """Classify the contact nodes of ``state`` for friction coefficient ``mu``.

    ``rtol`` is relative to the state's scales ``r_scale = max|r|`` and ``u_scale = max|u|``:

    - a normal reaction is zero when ``|r_N| <= rtol * r_scale`` (free if the gap is open,
      ``u_N < -rtol * u_scale``, else zero);
    - a node is on the cone (slip) when ``| |r_T| - mu |r_N| | <= rtol * (mu |r_N| + r_scale)``
      or beyond it: the same band from both sides of ``|r_T| = mu |r_N|``;
    - a tangential reaction ``|r_T| <= rtol * r_scale`` is round-off and has no sign: 0 is
      recorded, never the sign of the round-off. With ``mu = 0`` every loaded node is on the
      (degenerate) cone with sign 0: a frictionless state has no slip direction.
    """
    u_N, u_T, r_N, r_T = (np.asarray(v, dtype=float) for v in (state.u_N, state.u_T, state.r_N, state.r_T))
    r_scale = max(float(np.max(np.abs(np.concatenate([r_N, r_T])), initial=0.0)), 1e-300)
    u_scale = max(float(np.max(np.abs(np.concatenate([u_N, u_T])), initial=0.0)), 1e-300)
    # elementwise, the same double operations as the scalar rules above (NaN reactions: stick)
    unloaded = -r_N <= rtol * r_scale
    on_cone = ~unloaded & (np.abs(r_T) >= mu * (-r_N) - rtol * (mu * (-r_N) + r_scale))
    code = np.where(unloaded, np.where(u_N < -rtol * u_scale, 0, 1), np.where(on_cone, 3, 2))
    sign = np.where(on_cone & ~(np.abs(r_T) <= rtol * r_scale), np.where(r_T < 0, -1, 1), 0)
    return Classification(tuple(_STATUSES[code].tolist()), tuple(sign.tolist()))


#: status by code (0 free, 1 zero, 2 stick, 3 slip)
_STATUSES = np.array([FREE, ZERO, STICK, SLIP], dtype=object)


def frictionless_reason(cls: Classification, mu: float) -> str | None:
    """Why the stability analyses do not apply to ``cls``, or None when they do.

    With ``mu = 0`` there is no friction cone to slip on and ``K* = K0`` is SPD ((15) at mu = 0):
    no divergence. A slip node whose tangential reaction is round-off has no slip
    direction ``S``, so its pencil is undefined.
    """
    if mu == 0:
        return "not applicable: frictionless (K* = K0 is SPD, no divergence)"
    undefined = [i for i, (st, sg) in enumerate(zip(cls.status, cls.signs)) if st == SLIP and sg == 0]
    if undefined:
        return (f"not applicable: the tangential reaction of slip node(s) {undefined[:10]} is below the "
                f"classification tolerance (no slip direction S)")
    return None


def without_point_stick(cls: Classification, x) -> Classification | None:
    """``cls`` with its point stick zones slipping, or None when it has none.

    A point stick zone is a stuck node whose neighbours along the contact curve (``x``: each
    node's coordinate along it) are not stuck: a stick zone one node wide, which the mesh does not
    resolve. On the paper's block in plane strain it is the image of a zone 0.043 to 0.045 mm wide
    at corner A, one node on every uniform mesh down to h = 0.5 mm and 6 to 88 nodes on meshes
    graded towards A (docs/validation.md, "The stick zone at A resolved"). While ``h`` is far above
    the zone's width the stiffness it adds falls like ``1 / ln(L / h)``, and so do the quantities
    of its classification; the classification without it shows how much the unresolved zone
    weighs. It is not their limit: a zone of finite width keeps a finite stiffness. Each such
    node slips in the direction of a slipping neighbour, else of the majority of the slip nodes;
    None too when no node slips (no direction to give)."""
    order = np.argsort(np.asarray(x, dtype=float), kind="stable")
    status, signs = list(cls.status), list(cls.signs)
    slipping = [signs[i] for i in range(len(status)) if status[i] == SLIP]
    if not slipping:
        return None
    majority = 1 if sum(slipping) >= 0 else -1
    changed = False
    for k, i in enumerate(order):
        if cls.status[i] != STICK:
            continue
        near = [order[j] for j in (k - 1, k + 1) if 0 <= j < len(order)]
        if any(cls.status[j] == STICK for j in near):
            continue
        slip_near = [cls.signs[j] for j in near if cls.status[j] == SLIP]
        status[i], signs[i] = SLIP, (slip_near[0] if slip_near else majority)
        changed = True
    return Classification(status=tuple(status), signs=tuple(signs)) if changed else None
