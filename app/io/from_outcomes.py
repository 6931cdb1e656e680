"""The typed views of :mod:`app.io.result` built from a study's typed outcomes, not read back.

A finished study (:func:`app.study.run.study`) holds, for each state, the outcomes of its
analyses (:mod:`app.analyses.outcomes`) and the ``analyses`` block of results.json written from
them. :func:`state_view` turns them into a :class:`~app.io.result.StateResult` field by field
from the outcome objects; the block is kept only as each view's ``raw`` (the JSON data the same
outcomes serialise to, so :meth:`StudyResult.to_json` stays the file's text).

:meth:`StateResult.from_dict <app.io.result.StateResult.from_dict>` is the other constructor,
for saved files; ``tests/test_typed_result.py`` checks that both give equal views.

This module imports neither PETSc nor DOLFINx.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from app.analyses.outcomes import (
    Deferred,
    EnumerationOutcome,
    Failed,
    MceipLambda2Outcome,
    MceipMuOutcome,
    NecessaryOutcome,
    NotApplicable,
    Outcome,
    Solution,
    SufficientOutcome,
)
from app.io.result import (
    EVIDENCE_KEYS,
    CriticalMu,
    MceipResult,
    MceipSolution,
    NecessaryResult,
    Node,
    StateResult,
    SufficientResult,
    float_array,
)


def solution_view(sol: Solution, problem: str, raw: Mapping[str, Any]) -> MceipSolution:
    """One solution (``problem``: ``mu`` or ``lambda2``); ``raw`` its results.json entry."""
    ev = sol.evidence
    x = None
    if sol.x is not None:
        x = np.array(sol.x, dtype=np.float64)
        x.flags.writeable = False
    value = float(sol.value)
    return MceipSolution(value=CriticalMu(value) if problem == "mu" else value, x_Ts=float_array(sol.x_Ts),
                         pattern=tuple(sol.pattern), evidence={k: ev[k] for k in EVIDENCE_KEYS if k in ev},
                         raw=raw, certified=ev.get("certified"), certificate=ev.get("certificate"), x=x)


def _solutions(sols: list[Solution], problem: str, block: Mapping[str, Any]) -> tuple[MceipSolution, ...]:
    return tuple(solution_view(s, problem, r) for s, r in zip(sols, block["solutions"]))


def mceip_view(o: MceipMuOutcome | MceipLambda2Outcome, block: Mapping[str, Any]) -> MceipResult:
    """MCEIP-mu (21)-(23) or MCEIP-lambda^2 (12)-(14) at one state."""
    problem = "mu" if isinstance(o, MceipMuOutcome) else "lambda2"
    mu = getattr(o, "mu", None)
    return MceipResult(problem=problem, solutions=_solutions(o.solutions, problem, block), result=str(o.result),
                       search=o.search, raw=block, mu=None if mu is None else float(mu),
                       method=getattr(o, "method", None), certified=o.certified, certificate=block["certificate"])


def enumeration_view(o: EnumerationOutcome, block: Mapping[str, Any]) -> MceipResult:
    """The enumeration (24)-(26): the first requested problem's answer (its block's top level)."""
    p = o.problems[o.first]
    return MceipResult(problem=p.problem, solutions=_solutions(p.solutions, p.problem, block), result="",
                       search={}, raw=block, mu=None if p.mu is None else float(p.mu), certified=p.certified,
                       certificate=block.get("certificate"))


def state_view(entry: Mapping[str, Any], nodes: tuple[Node, ...], analyses: Mapping[str, Outcome],
               blocks: Mapping[str, Mapping[str, Any]]) -> StateResult:
    """One state: ``entry`` its results.json entry (index, load, classification, ...), ``nodes``
    its contact nodes, ``analyses`` the outcomes and ``blocks`` their results.json entries."""
    if any(isinstance(a, Deferred) for a in analyses.values()):
        raise ValueError(f"state {entry['index']}: an analysis is still deferred")
    done = {k: a for k, a in analyses.items() if not isinstance(a, (Failed, NotApplicable))}
    nec, suf = done.get("necessary"), done.get("sufficient")
    lam, enum, mu = done.get("mceip_lambda2"), done.get("enumerate"), done.get("mceip_mu")
    assert nec is None or isinstance(nec, NecessaryOutcome)
    assert suf is None or isinstance(suf, SufficientOutcome)
    return StateResult(
        index=int(entry["index"]), load=entry.get("load") or {}, classification=entry.get("classification") or {},
        nodes=nodes, analyses_shared_with=entry.get("analyses_shared_with"),
        necessary=None if nec is None else NecessaryResult(bool(nec.satisfied), float(nec.min_eig_K_sym),
                                                           float(nec.min_eig_M_sym), blocks["necessary"]),
        sufficient=None if suf is None else SufficientResult(
            bool(suf.satisfied), float_array(suf.lambda2), _modes(suf, blocks["sufficient"]), blocks["sufficient"]),
        mceip_mu=None if mu is None else mceip_view(mu, blocks["mceip_mu"]),
        mceip_lambda2=None if lam is None else mceip_view(lam, blocks["mceip_lambda2"]),
        enumerate=None if enum is None else enumeration_view(enum, blocks["enumerate"]),
        failed={k: a.reason for k, a in analyses.items() if isinstance(a, Failed)},
        raw=entry)


def _modes(o: SufficientOutcome, block: Mapping[str, Any]) -> tuple[MceipSolution, ...]:
    return tuple(solution_view(m, "lambda2", r) for m, r in zip(o.modes, block["modes"]))
