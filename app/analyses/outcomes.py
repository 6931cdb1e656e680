"""Typed outcomes of the analyses of one classified state, and their one serialisation.

Every analysis of :mod:`app.analyses.runner` returns one of these dataclasses; the study keeps
them as they are and the ``analyses`` block of results.json is written from them by
:func:`analyses_document` (each type's ``as_dict``), the only place where they become dicts.
The typed reader of a saved results.json is :mod:`app.io.result`.

Evidence whose fields depend on the solver that produced it (the ``search`` record of a search,
the ``detail`` of a certificate, the residuals and provenance of a solution) stays an ordered
mapping: its keys are written as they are.

This module imports neither PETSc nor DOLFINx.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Union

import numpy as np

#: the status of a claim that a wall-clock safety stop (``settings.mcp.certify_seconds`` and the
#: other ``*_seconds`` keys, off by default) ended; the budgets themselves count work (tree nodes,
#: supports), so "not proven" never depends on the machine's speed
STOPPED = "stopped by the time limit"


@dataclass(frozen=True)
class Failed:
    """An analysis whose solver failed (PETSc/SLEPc error, no convergence, unsupported state);
    ``reason`` is one line, ``"<error type>: <message>"``."""

    reason: str

    def as_dict(self) -> dict:
        """The results.json entry."""
        return {"failed": True, "reason": self.reason}


@dataclass(frozen=True)
class NotApplicable:
    """An analysis with nothing to compute at this state (no friction effect, nothing can move)."""

    reason: str

    def as_dict(self) -> dict:
        """The results.json entry."""
        return {"not_applicable": True, "reason": self.reason}


@dataclass(frozen=True)
class Deferred:
    """The condensed MCEIP-mu (21)-(23) left for :mod:`app.study.scheduler`, which replaces
    it by its outcome (never in a finished study)."""

    def as_dict(self) -> dict:
        """The in-memory entry (a finished study holds none)."""
        return {"deferred": True}


@dataclass
class Solution:
    """One solution of an MCEIP (MCEIP-mu (21)-(23), MCEIP-lambda^2 (12)-(14), enumeration
    (24)-(26)) or one admissible mode of the sufficient condition (17)-(18).

    ``value`` is mu or lambda^2; ``x_Ts`` the mode on the slip nodes (sum 1, A to B);
    ``pattern`` slip/stick per slip node; ``evidence`` the solver's evidence in results.json
    order (residual, complementarity, ``found_by``, ``certified``, enclosures, ...); ``x`` the
    full kept-space vector when kept in memory for mode shapes (never in results.json).
    """

    value: float
    x_Ts: list[float]
    pattern: list[str]
    evidence: dict[str, Any] = field(default_factory=dict)
    x: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def from_fields(cls, d: Mapping[str, Any]) -> "Solution":
        """From a solver's solution record (``value``, ``x_Ts``, ``pattern``, then the evidence)."""
        rest = {k: v for k, v in d.items() if k not in ("value", "x_Ts", "pattern")}
        return cls(value=d["value"], x_Ts=d["x_Ts"], pattern=d["pattern"], evidence=rest)

    @property
    def certified(self) -> bool | None:
        """The solution is proven (None when the analysis says nothing about it)."""
        return self.evidence.get("certified")

    def mark(self, **evidence: Any) -> None:
        """Set evidence fields (an existing one keeps its place in the record)."""
        self.evidence.update(evidence)

    def as_dict(self) -> dict:
        """The results.json entry (``x`` stays in memory: app/io/from_outcomes.py)."""
        return {"value": self.value, "x_Ts": self.x_Ts, "pattern": self.pattern, **self.evidence}


@dataclass
class Certificate:
    """What an MCEIP outcome proves: ``status`` about ``interval`` of the eigenvalue (``"proven"``
    only when every solution in it is listed), by ``method``; ``gap`` the unproven share of the
    interval, ``seconds`` None when not timed, ``detail`` the method's own evidence,
    ``rigorous`` every step has a rigorous rounding bound. The MCEIP-mu proofs (21)-(23) add
    ``cap`` and the proven ``onset`` (and the ``ill_conditioned`` values)."""

    method: str
    interval: tuple[float, float]
    status: str
    gap: float | None = None
    seconds: float | None = None
    detail: dict[str, Any] = field(default_factory=dict)
    rigorous: bool = True
    cap: float | None = None
    onset: float | None = None
    ill_conditioned: list[float] | None = None

    def as_dict(self) -> dict:
        """The results.json ``certificate`` block."""
        out = {"method": self.method, "interval": [float(self.interval[0]), float(self.interval[1])],
               "status": self.status, "gap": self.gap, "seconds": self.seconds, "detail": self.detail,
               "rigorous": self.rigorous}
        if self.cap is not None:
            out.update(cap=self.cap, onset=self.onset)
        if self.ill_conditioned:
            out["ill_conditioned"] = self.ill_conditioned
        return out


@dataclass(frozen=True)
class NecessaryOutcome:
    """Necessary condition (19) at ``mu``: the smallest eigenvalues of sym K*(mu) and sym M*(mu)
    (absolute and relative to the largest diagonal entry); ``satisfied`` when K* is not PD or M*
    not PSD (divergence possible)."""

    mu: float
    min_eig_K_sym: float | None
    min_eig_K_sym_relative: float | None
    min_eig_M_sym: float | None
    min_eig_M_sym_relative: float | None
    satisfied: bool
    # where the values' budget on the contact DOFs was spent: the value is None and lies in these
    # bounds (absolute and relative), its sign decided
    min_eig_K_sym_bounds: tuple[float, float] | None = None
    min_eig_K_sym_relative_bounds: tuple[float, float] | None = None
    min_eig_M_sym_bounds: tuple[float, float] | None = None
    min_eig_M_sym_relative_bounds: tuple[float, float] | None = None

    def lower(self, name: str) -> float:
        """A lower bound on the smallest eigenvalue of ``sym K*`` (``name`` "K") or ``sym M*`` ("M"):
        the value, or its lower bound."""
        v = getattr(self, f"min_eig_{name}_sym")
        return v if v is not None else getattr(self, f"min_eig_{name}_sym_bounds")[0]

    def as_dict(self) -> dict:
        """The results.json ``necessary`` block."""
        out = {"mu": self.mu, "min_eig_K_sym": self.min_eig_K_sym,
               "min_eig_K_sym_relative": self.min_eig_K_sym_relative, "min_eig_M_sym": self.min_eig_M_sym,
               "min_eig_M_sym_relative": self.min_eig_M_sym_relative, "satisfied": self.satisfied}
        for name in ("K", "M"):
            if getattr(self, f"min_eig_{name}_sym_bounds") is not None:
                out[f"min_eig_{name}_sym_bounds"] = list(getattr(self, f"min_eig_{name}_sym_bounds"))
                out[f"min_eig_{name}_sym_relative_bounds"] = list(getattr(self, f"min_eig_{name}_sym_relative_bounds"))
        return out


@dataclass
class SufficientOutcome:
    """Sufficient condition (17)-(18): the admissible real eigenpairs lambda^2 > 0 with x_Ts >= 0
    of (lambda^2 M* + K*) x = 0 (``lambda2`` descending, their ``modes``), every real candidate
    examined, the eigensolver and how many eigenpairs it converged; ``mu`` the friction
    coefficient (set by the runner)."""

    satisfied: bool
    lambda2: list[float]
    modes: list[Solution]
    real_candidates: list[dict]
    eigensolver: str
    converged: int
    mu: float | None = None

    def as_dict(self) -> dict:
        """The results.json ``sufficient`` block."""
        out = {"satisfied": self.satisfied, "lambda2": self.lambda2, "modes": [m.as_dict() for m in self.modes],
               "real_candidates": self.real_candidates, "eigensolver": self.eigensolver, "converged": self.converged}
        if self.mu is not None:
            out["mu"] = self.mu
        return out


@dataclass(frozen=True)
class OnsetClaim:
    """MCEIP-mu (21)-(23): the smallest critical mu (``value``, None for none in ``[0, cap]``)
    with its ``enclosure``; ``proven`` when the checker accepted it."""

    proven: bool
    status: str
    value: float | None = None
    enclosure: list[float] | None = None

    def as_dict(self) -> dict:
        """The results.json ``onset`` block."""
        return {"proven": self.proven, "status": self.status, "value": self.value, "enclosure": self.enclosure}


@dataclass(frozen=True)
class CompleteClaim:
    """MCEIP-mu (21)-(23): every critical mu in ``interval`` is listed (``count`` of them, None
    when not proven)."""

    proven: bool
    status: str
    interval: list[float]
    count: int | None = None

    def as_dict(self) -> dict:
        """The results.json ``complete`` block."""
        return {"proven": self.proven, "status": self.status, "interval": self.interval, "count": self.count}


@dataclass
class _Solved:
    """What every MCEIP outcome has: the ``solutions`` found, the one-line ``result``, the
    ``search`` record, ``certified`` and the ``certificate`` of what is proven."""

    solutions: list[Solution]
    result: str
    search: dict[str, Any]
    certified: bool
    certificate: Certificate


@dataclass
class MceipMuOutcome(_Solved):
    """MCEIP-mu (21)-(23) at one state: the ``solutions`` (critical mu, ascending), the one-line
    ``result``, the ``onset`` and ``complete`` claims of the proof (None for the full-size
    search, which proves nothing), the ``certificate``, the ``search`` record and the
    ``method`` (condensed, condensed (quadratic), full, ...). ``quadratic`` on a curved
    obstacle; ``extra`` the zero-reaction-node notes; ``proof`` the pencil and proof log written
    to ``proofs/`` (never in results.json)."""

    onset: OnsetClaim | None = None
    complete: CompleteClaim | None = None
    method: str | None = None
    quadratic: bool = False
    extra: dict[str, Any] = field(default_factory=dict)
    proof: dict[str, Any] | None = field(default=None, repr=False)

    def as_dict(self) -> dict:
        """The results.json ``mceip_mu`` block (``proof`` stays in memory: app/io/from_outcomes.py)."""
        out: dict = {"solutions": [s.as_dict() for s in self.solutions], "result": self.result,
                     "certified": self.certified}
        if self.onset is not None:
            out["onset"] = self.onset.as_dict()
        if self.complete is not None:
            out["complete"] = self.complete.as_dict()
        out["certificate"] = self.certificate.as_dict()
        out["search"] = self.search
        if self.quadratic:
            out["quadratic"] = True
        out.update(self.extra)
        if self.method is not None:
            out["method"] = self.method
        return out


@dataclass
class MceipLambda2Outcome(_Solved):
    """MCEIP-lambda^2 (12)-(14) at the friction coefficient ``mu``: the ``solutions`` found, the
    one-line ``result``, the ``search`` record (with the necessary condition and the proven upper
    bound), ``certified`` and the ``certificate`` of what is proven; ``extra`` the
    zero-reaction-node notes."""

    mu: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The results.json ``mceip_lambda2`` block."""
        out: dict = {"solutions": [s.as_dict() for s in self.solutions], "result": self.result,
                     "search": self.search, **self.extra, "certified": self.certified,
                     "certificate": self.certificate.as_dict()}
        if self.mu is not None:
            out["mu"] = self.mu
        return out


@dataclass
class EnumerationProblem:
    """The exhaustive enumeration (24)-(26) of one problem (``mu`` or ``lambda2``, at ``mu``):
    every support solved (``complete``) or ``refused`` (too many slip nodes)."""

    problem: str
    solutions: list[Solution]
    complete: bool
    certified: bool | None = None
    certificate: Certificate | None = None
    mu: float | None = None
    refused: str | None = None

    def as_dict(self) -> dict:
        """The results.json entry of one enumerated problem."""
        out: dict = {"problem": self.problem, "solutions": [s.as_dict() for s in self.solutions],
                     "complete": self.complete}
        if self.refused is not None:
            out["refused"] = self.refused
        if self.certified is not None:
            out["certified"] = self.certified
        if self.certificate is not None:
            out["certificate"] = self.certificate.as_dict()
        if self.mu is not None:
            out["mu"] = self.mu
        return out


@dataclass
class EnumerationOutcome:
    """The enumeration (24)-(26) of every requested problem; ``first`` the one shown at the top
    level of the results.json block (the first requested)."""

    problems: dict[str, EnumerationProblem]
    first: str

    def as_dict(self) -> dict:
        """The results.json ``enumerate`` block: the first problem's fields and ``problems``."""
        problems = {k: p.as_dict() for k, p in self.problems.items()}
        return {**problems[self.first], "problems": problems}


#: what an analysis of :mod:`app.analyses.runner` returns
Outcome = Union[Failed, NotApplicable, Deferred, NecessaryOutcome, SufficientOutcome, MceipMuOutcome,
                MceipLambda2Outcome, EnumerationOutcome]


def analyses_document(analyses: Mapping[str, Outcome]) -> dict:
    """The ``analyses`` block of one state of results.json (analysis name -> its entry)."""
    return {name: a.as_dict() for name, a in analyses.items()}


def one_line(err: BaseException) -> Failed:
    """The :class:`Failed` outcome of a solver error: its type and the first line of its message."""
    return Failed(f"{type(err).__name__}: {err}".splitlines()[0])
