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
        """States with equal keys have identical reduced pencils (DESIGN.md section 3)."""
        return self.status, tuple(s if st == SLIP else 0 for s, st in zip(self.signs, self.status))

    def indices(self, status: str) -> np.ndarray:
        return np.array([i for i, s in enumerate(self.status) if s == status], dtype=np.int64)

    @property
    def slip(self) -> np.ndarray:
        return self.indices(SLIP)

    @property
    def slip_signs(self) -> np.ndarray:
        return np.array([self.signs[i] for i in self.slip], dtype=float)

    def counts(self) -> dict[str, int]:
        return {s: self.status.count(s) for s in (FREE, ZERO, STICK, SLIP)}

    def label(self) -> str:
        c = self.counts()
        return f"{c[STICK]} stick / {c[SLIP]} slip / {c[FREE]} free" + (f" / {c[ZERO]} zero" if c[ZERO] else "")


def classify(state: EquilibriumState, mu: float, rtol: float = 1e-8) -> Classification:
    """Classify the contact nodes of ``state`` for friction coefficient ``mu``.

    ``rtol`` is relative: a normal reaction is zero when ``|r_N| <= rtol * max|r|``, a gap is
    closed when ``|u_N| <= rtol * max|u|``, and a node is on the cone when
    ``|r_T| >= (1 - rtol) * mu * |r_N|``.
    """
    r_scale = max(float(np.max(np.abs(np.concatenate([state.r_N, state.r_T])), initial=0.0)), 1e-300)
    u_scale = max(float(np.max(np.abs(np.concatenate([state.u_N, state.u_T])), initial=0.0)), 1e-300)
    status, signs = [], []
    for uN, rN, rT in zip(state.u_N, state.r_N, state.r_T):
        if -rN <= rtol * r_scale:
            status.append(FREE if uN < -rtol * u_scale else ZERO)
            signs.append(0)
        elif abs(rT) >= (1.0 - rtol) * mu * (-rN):
            # On the cone. With mu = 0 (r_T = 0) the sign is ambiguous; +1 is recorded.
            status.append(SLIP)
            signs.append(-1 if rT < 0 else 1)
        else:
            status.append(STICK)
            signs.append(0)
    return Classification(tuple(status), tuple(signs))
