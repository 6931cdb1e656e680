"""Equilibrium states along a loading path (paper eq. (5)-(7)), in the paper's axes."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np


@dataclass
class EquilibriumState:
    """Contact displacements and reactions of every contact node at one equilibrium state.

    Paper convention: ``u_N <= 0`` (no penetration), ``r_N <= 0`` (compression),
    ``|r_T| <= -mu r_N``.
    """

    index: int
    load: dict
    u_T: np.ndarray
    u_N: np.ndarray
    r_T: np.ndarray
    r_N: np.ndarray
    extra: dict = field(default_factory=dict)
    #: the classification the loading path made of this state (to see gross sliding) with its
    #: friction coefficient and tolerance: the study reuses it for the same ``(mu, rtol)``
    classified: Optional[tuple[float, float, Any]] = field(default=None, repr=False)
