"""Typed, read-only views of a study's results (what ``results.json`` holds).

A finished study (`app.study.run.study`) returns a [`StudyResult`][app.io.result.StudyResult] whose states are
built from the analyses' typed outcomes (`app.analyses.outcomes`, via
app/io/from_outcomes.py); its ``raw`` is the results dictionary written from those same outcomes,
so [`StudyResult.to_json`][app.io.result.StudyResult.to_json] is exactly the ``results.json`` content. [`StudyResult.load`][app.io.result.StudyResult.load]
and [`StudyResult.from_dict`][app.io.result.StudyResult.from_dict] build the same views from a saved file (any format version);
``tests/test_typed_result.py`` checks that the two constructions agree field by field.

The queries the outputs need ([`StudyResult.first_instability`][app.io.result.StudyResult.first_instability], [`StateResult.min_mu`][app.io.result.StateResult.min_mu],
[`StudyResult.final`][app.io.result.StudyResult.final], [`StudyResult.state`][app.io.result.StudyResult.state], ...) are written here once.

This module imports neither PETSc nor DOLFINx: it also reads results saved by earlier runs.

Notation (the paper's, as in ``docs/method.md``): ``x_Ts`` is the tangential rate of
the slip nodes in a mode, normalised to sum 1, listed from A to B; ``pattern[i]`` is ``slip``
where ``x_Ts[i] > 0`` and ``stick`` where it is 0.
"""
from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

import numpy as np

from app.io.document import from_document, to_document

#: keys of an MCEIP solution dictionary that are the evidence that it is one (app/analyses/snes_vi/search.py, app/analyses/enumerate.py)
EVIDENCE_KEYS = ("residual", "complementarity", "min_x_Ts", "min_y_Ts", "iterations", "found_by",
                 "found_count", "relative_error")


class CriticalMu(float):
    """A critical friction coefficient of MCEIP-mu (21)-(23).

    It is a ``float`` with the full double-precision value (arithmetic, ``repr``, ``to_json``,
    format specs such as ``f"{mu:.10g}"`` all see every digit). Only ``str()`` (hence ``print``
    and ``f"{mu}"``) rounds, to 4 decimals: mu is dimensionless and the paper and the README
    quote it so (1.7048, 60.8058); the solver's accuracy is far better (acceptance 1e-8), the
    mesh error of the final value is about 3e-3 (README, refinement table).
    """

    def __str__(self) -> str:
        return f"{float(self):.4f}"


def _float(v: Any) -> float:
    """A number of the results (``None``: not a number; format 1's ``"inf"`` strings parse too)."""
    return math.nan if v is None else float(v)


def float_array(values: Any) -> np.ndarray:
    """Read-only float64 array of ``values`` (``None`` entries: NaN)."""
    a = np.asarray([_float(v) for v in (values or [])], dtype=np.float64)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class MceipSolution:
    """One solution of an MCEIP (or one sufficient-condition mode) and the evidence for it.

    ``value`` is mu (MCEIP-mu), lambda^2 [1/s^2] (MCEIP-lambda^2, sufficient condition);
    ``x_Ts`` the mode on the slip nodes (sum 1, A to B); ``pattern`` slip/stick per slip node;
    ``evidence`` residual, complementarity violation, iterations, ``found_by`` (method and start);
    ``certified``/``certificate`` are present when the analysis proved the solution;
    ``x`` is the full kept-space vector of (10) when the analysis kept it in memory (never in
    results.json); ``raw`` the solution's dictionary as in results.json.
    """

    value: float
    x_Ts: np.ndarray
    pattern: tuple[str, ...]
    evidence: Mapping[str, Any]
    raw: Mapping[str, Any] = field(repr=False)
    certified: bool | None = None
    certificate: Mapping[str, Any] | None = None
    x: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], problem: str = "mu") -> "MceipSolution":
        """Build from one solution dictionary of results.json."""
        value = _float(d.get("value"))
        x = d.get("_x")
        if x is not None:
            x = np.array(x, dtype=np.float64)
            x.flags.writeable = False
        return cls(value=CriticalMu(value) if problem == "mu" else value, x_Ts=float_array(d.get("x_Ts")),
                   pattern=tuple(d.get("pattern") or ()),
                   evidence={k: d[k] for k in EVIDENCE_KEYS if k in d}, raw=d,
                   certified=d.get("certified"), certificate=d.get("certificate"), x=x)

    @property
    def all_slip(self) -> bool:
        """Every slip node of the state keeps slipping in this mode."""
        return all(p == "slip" for p in self.pattern)

    @property
    def n_stick(self) -> int:
        """Slip nodes of the state that stick in this mode."""
        return sum(p == "stick" for p in self.pattern)


@dataclass(frozen=True)
class MceipResult:
    """The answer of one MCEIP analysis at one state (``mceip_mu``, ``mceip_lambda2`` or ``enumerate``).

    ``solutions`` sorted by value; ``result`` the one-line answer (found / none found / proven);
    ``search`` how the search was bounded (``complete`` is true only for a proof); ``mu`` the
    friction coefficient of MCEIP-lambda^2; ``failed``/``reason`` when the solver failed.
    """

    problem: str
    solutions: tuple[MceipSolution, ...]
    result: str
    search: Mapping[str, Any]
    raw: Mapping[str, Any] = field(repr=False)
    mu: float | None = None
    method: str | None = None
    failed: bool = False
    reason: str | None = None
    certified: bool | None = None
    certificate: Mapping[str, Any] | None = None

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], problem: str) -> "MceipResult":
        """Build from one analysis dictionary of results.json (``problem``: ``mu`` or ``lambda2``)."""
        problem = d.get("problem", problem)
        sols = tuple(MceipSolution.from_dict(s, problem) for s in d.get("solutions") or [])
        return cls(problem=problem, solutions=sols, result=str(d.get("result", "")),
                   search=d.get("search") or {}, raw=d,
                   mu=None if d.get("mu") is None else _float(d["mu"]), method=d.get("method"),
                   failed=bool(d.get("failed", False)), reason=d.get("reason"),
                   certified=d.get("certified"), certificate=d.get("certificate"))

    @property
    def values(self) -> np.ndarray:
        """Every eigenvalue found, ascending."""
        return float_array([s.value for s in self.solutions])

    def min(self) -> float | None:
        """The smallest eigenvalue found (a [`CriticalMu`][app.io.result.CriticalMu] for MCEIP-mu), or None if none."""
        return min((s.value for s in self.solutions), default=None)

    def max(self) -> float | None:
        """The largest eigenvalue found, or None if none."""
        return max((s.value for s in self.solutions), default=None)


@dataclass(frozen=True)
class NecessaryResult:
    """Necessary condition (19) at mu: smallest eigenvalues of sym K*(mu) and sym M*(mu)."""

    satisfied: bool
    min_eig_K_sym: float
    min_eig_M_sym: float
    raw: Mapping[str, Any] = field(repr=False)


@dataclass(frozen=True)
class SufficientResult:
    """Sufficient condition (17)-(18): admissible real eigenpairs lambda^2 > 0 with x_Ts >= 0."""

    satisfied: bool
    lambda2: np.ndarray
    modes: tuple[MceipSolution, ...]
    raw: Mapping[str, Any] = field(repr=False)


@dataclass(frozen=True)
class Node:
    """A contact node at one state (paper sign convention: r_N <= 0 compressive, u_N <= 0)."""

    id: int
    x: float
    status: str
    sign: int
    u_N: float
    u_T: float
    r_N: float
    r_T: float


@dataclass(frozen=True)
class StateResult:
    """One equilibrium state: load, classification, contact nodes and analyses.

    ``analyses_shared_with`` is the index of the state whose analyses this state shares (same
    classification and signs), None when they were computed here.
    """

    index: int
    load: Mapping[str, Any]
    classification: Mapping[str, int]
    nodes: tuple[Node, ...]
    analyses_shared_with: int | None
    necessary: NecessaryResult | None
    sufficient: SufficientResult | None
    mceip_mu: MceipResult | None
    mceip_lambda2: MceipResult | None
    enumerate: MceipResult | None
    failed: Mapping[str, str]
    raw: Mapping[str, Any] = field(repr=False)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "StateResult":
        """Build from one entry of results.json ``states``."""
        a = d.get("analyses") or {}
        ok = {k: v for k, v in a.items() if not v.get("failed") and not v.get("not_applicable")}
        nec = ok.get("necessary")
        suf = ok.get("sufficient")
        enum = ok.get("enumerate")
        return cls(
            index=int(d["index"]), load=d.get("load") or {}, classification=d.get("classification") or {},
            nodes=tuple(Node(id=int(n["id"]), x=_float(n["x"]), status=n["status"], sign=int(n["sign"]),
                             u_N=_float(n.get("u_N")), u_T=_float(n.get("u_T")), r_N=_float(n.get("r_N")),
                             r_T=_float(n.get("r_T"))) for n in d.get("nodes") or []),
            analyses_shared_with=d.get("analyses_shared_with"),
            necessary=None if nec is None else NecessaryResult(bool(nec["satisfied"]), _float(nec.get("min_eig_K_sym")),
                                                               _float(nec.get("min_eig_M_sym")), nec),
            sufficient=None if suf is None else SufficientResult(
                bool(suf["satisfied"]), float_array(suf.get("lambda2")),
                tuple(MceipSolution.from_dict(m, "lambda2") for m in suf.get("modes") or []), suf),
            mceip_mu=None if "mceip_mu" not in ok else MceipResult.from_dict(ok["mceip_mu"], "mu"),
            mceip_lambda2=None if "mceip_lambda2" not in ok else MceipResult.from_dict(ok["mceip_lambda2"], "lambda2"),
            enumerate=None if enum is None else MceipResult.from_dict(enum, enum.get("problem", "mu")),
            failed={k: str(v.get("reason", "")) for k, v in a.items() if v.get("failed")},
            raw=d)

    def min_mu(self) -> CriticalMu | None:
        """Smallest critical friction coefficient found by MCEIP-mu at this state, None if none.

        ``print`` shows 4 decimals; the value itself is the full float (see [`CriticalMu`][app.io.result.CriticalMu]).
        """
        return None if self.mceip_mu is None else self.mceip_mu.min()

    def mu_values(self) -> np.ndarray:
        """Every MCEIP-mu value found at this state, ascending (empty if none or not asked)."""
        return float_array([]) if self.mceip_mu is None else self.mceip_mu.values

    def max_lambda2(self) -> float | None:
        """Largest admissible lambda^2 of the sufficient condition (17)-(18), None if none."""
        if self.sufficient is None or not len(self.sufficient.lambda2):
            return None
        return float(np.max(self.sufficient.lambda2))

    def counts(self) -> str:
        """``stick / slip / free`` node counts (and zero-reaction nodes if any), for messages."""
        c = self.classification
        return (f"{c.get('stick', 0)} stick / {c.get('slip', 0)} slip / {c.get('free', 0)} free"
                + (f" / {c['zero']} zero" if c.get("zero") else ""))


@dataclass(frozen=True)
class StudyResult:
    """A whole study: the loading path's states and their analyses, with the run's evidence.

    Build it with [`app.run_study`][app.api.run_study], or from a saved ``results.json`` with [`load`][app.io.result.StudyResult.load].
    """

    scene: str
    system: str
    mu: float
    units: Mapping[str, str]
    analyses_requested: tuple[str, ...]
    path: Mapping[str, Any]
    failures: tuple[Mapping[str, Any], ...]
    warnings: tuple[str, ...]
    states: tuple[StateResult, ...]
    raw: Mapping[str, Any] = field(repr=False)

    @classmethod
    def from_dict(cls, results: Mapping[str, Any]) -> "StudyResult":
        """Wrap a results dictionary (as returned by app.study.run.run_study or read from results.json)."""
        return cls(scene=str(results.get("scene", "")), system=str(results.get("system", "")),
                   mu=_float(results.get("mu")), units=results.get("units") or {},
                   analyses_requested=tuple(results.get("analyses_requested") or ()),
                   path=results.get("path") or {}, failures=tuple(results.get("failures") or ()),
                   warnings=tuple(results.get("warnings") or ()),
                   states=tuple(StateResult.from_dict(s) for s in results.get("states") or []),
                   raw=results)

    @classmethod
    def load(cls, path: str | pathlib.Path) -> "StudyResult":
        """Read a ``results.json`` (or the results folder holding it)."""
        p = pathlib.Path(path)
        if p.is_dir():
            p = p / "results.json"
        return cls.from_dict(from_document(json.loads(p.read_text(encoding="utf-8"))))

    def __len__(self) -> int:
        return len(self.states)

    def __iter__(self) -> Iterator[StateResult]:
        return iter(self.states)

    @property
    def final(self) -> StateResult:
        """The last equilibrium state of the path."""
        return self.states[-1]

    def state(self, index: int) -> StateResult:
        """The state with this ``index`` (state indices follow the loading path from 0)."""
        for s in self.states:
            if s.index == index:
                return s
        raise KeyError(f"no state {index} (indices {self.states[0].index} to {self.states[-1].index})"
                       if self.states else f"no state {index}: the study has no states")

    def first_instability(self) -> StateResult | None:
        """The first state along the path at which MCEIP-mu has a solution (a critical mu), or None.

        It is the first state where divergence is possible for some friction coefficient; whether
        it is possible for the scene's mu is the question of MCEIP-lambda^2 and (17)-(18).
        """
        return next((s for s in self.states if s.mceip_mu is not None and s.mceip_mu.solutions), None)

    def min_mu_along_path(self) -> np.ndarray:
        """Smallest MCEIP-mu value at every state (NaN where none was found)."""
        return float_array([math.nan if (m := s.min_mu()) is None else m for s in self.states])

    @property
    def complete(self) -> bool:
        """No state failed (the CLI exits with status 3 otherwise)."""
        return not self.failures

    def to_json(self) -> dict:
        """The results.json document, exactly as the CLI writes it (`to_document`).

        JSON-ready (finite numbers, strings, lists, dicts); in-memory vectors (``_x``) are left out
        and non-finite numbers written as ``null`` and listed in the ``non_finite`` block.
        """
        return to_document(self.raw)
