"""Solutions of the MCEIPs (paper (12)-(14), (21)-(23)) with their evidence, and the record of a search.

Shared by the full-size SNES VI search (:mod:`app.analyses.snes_vi.search`) and its bordered MCP
(:mod:`app.analyses.snes_vi.bordered`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.analyses.outcomes import Solution


@dataclass
class McpSolution:
    """One solution of an MCEIP, with the evidence that it is one."""

    value: float
    x_c: np.ndarray             # complementarity block x_Ts, normalised to sum 1
    pattern: list[str]          # "slip" where x_c > 0, "stick" where x_c = 0
    residual: float             # max |y_f| / scale
    complementarity: float      # max |x_c y_c| / scale
    min_x: float
    min_y: float                # min y_c / scale
    found_by: list[str] = field(default_factory=list)
    iterations: int = 0
    x: np.ndarray | None = None  # full kept-space vector (replicated), for mode shapes
    pattern_residual: float = 0.0   # residual of the pattern's restricted eigenproblem (25)-(26) / scale
    pattern_verified: bool = True   # the pattern solves its restricted eigenproblem to the tolerance

    def as_solution(self, keep_vector: bool = False) -> Solution:
        """The typed solution of the outcome (with the full vector ``x`` when ``keep_vector``)."""
        return Solution(value=float(self.value), x_Ts=[float(v) for v in self.x_c], pattern=self.pattern,
                        evidence={"residual": self.residual, "complementarity": self.complementarity,
                                  "min_x_Ts": self.min_x, "min_y_Ts": self.min_y, "iterations": self.iterations,
                                  "found_by": self.found_by[:8], "found_count": len(self.found_by),
                                  "pattern_residual": self.pattern_residual,
                                  "pattern_verified": self.pattern_verified},
                        x=self.x if keep_vector else None)

    def as_dict(self) -> dict:
        """The solution's results.json entry."""
        return self.as_solution().as_dict()


@dataclass
class SearchReport:
    """All distinct solutions found and how the search was bounded."""

    problem: str
    solutions: list[McpSolution]
    attempts: int = 0
    converged: int = 0
    accepted: int = 0
    by_method: dict = field(default_factory=dict)
    intervals: list[str] = field(default_factory=list)
    starts: list[str] = field(default_factory=list)
    skipped_identical: int = 0

    def typed_solutions(self, keep_vectors: bool = False) -> list[Solution]:
        """The distinct solutions by value, typed (with their full vectors when ``keep_vectors``)."""
        return [s.as_solution(keep_vectors) for s in sorted(self.solutions, key=lambda s: s.value)]

    def result(self) -> str:
        """The one-line answer of the search (found, or none found: not a proof of absence)."""
        return (f"{len(self.solutions)} distinct solution(s) found" if self.solutions else
                f"no solution found in {self.intervals[0]} from {len(self.starts)} start vector(s), "
                f"{self.attempts} SNES VI runs ({self.converged} converged, none satisfied the "
                f"MCP to the acceptance tolerance); not a proof of absence")

    def search(self) -> dict:
        """The ``search`` record: how the search was bounded."""
        return {"attempts": self.attempts, "converged": self.converged,
                "accepted": self.accepted, "by_method": self.by_method,
                "intervals": self.intervals, "starts": self.starts,
                "identical_runs_skipped": self.skipped_identical,
                "complete": False,
                "note": "MCP search: distinct solutions found from the listed starts and "
                        "intervals; completeness is proven only by enumeration"}

    def as_dict(self) -> dict:
        """``solutions``, ``result`` and ``search`` as in results.json."""
        return {"solutions": [s.as_dict() for s in self.typed_solutions()], "result": self.result(),
                "search": self.search()}
