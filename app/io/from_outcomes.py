"""The typed analyses of a state (:class:`app.io.result.Analyses`) from the analyses' outcomes.

The analyses of :mod:`app.analyses.runner` return typed outcomes (:mod:`app.analyses.outcomes`),
whose ``as_dict`` is their results.json entry; :func:`analyses_result` reads that entry into the
result's models (app/io/result.py, the one description of the format) and adds what a run keeps in
memory only, never written: each mode's kept-space vector (``MceipSolution.x``, for the mode
fields of app/io/fields.py) and the pencil and proof log of an MCEIP-mu proof
(``MceipMuResult.proof``, for ``proofs/``, app/io/proofs.py).

This module imports neither PETSc nor DOLFINx.
"""
from __future__ import annotations

from typing import Mapping, Sequence

from app.analyses.outcomes import (
    Deferred,
    EnumerationOutcome,
    MceipLambda2Outcome,
    MceipMuOutcome,
    Outcome,
    Solution,
    SufficientOutcome,
    analyses_document,
)
from app.io.result import Analyses, MceipSolution


def analyses_result(analyses: Mapping[str, Outcome]) -> Analyses:
    """The typed analyses of one classification (analysis name -> its finished outcome)."""
    if any(isinstance(a, Deferred) for a in analyses.values()):
        raise ValueError("an analysis is still deferred")
    typed = Analyses.model_validate(analyses_document(analyses))
    for name, o in analyses.items():
        t = getattr(typed, name, None)
        if t is None:
            continue
        if isinstance(o, MceipMuOutcome):
            t.proof = o.proof
            _keep_vectors(o.solutions, t.solutions)
        elif isinstance(o, MceipLambda2Outcome):
            _keep_vectors(o.solutions, t.solutions)
        elif isinstance(o, SufficientOutcome):
            _keep_vectors(o.modes, t.modes)
        elif isinstance(o, EnumerationOutcome):
            _keep_vectors(o.problems[o.first].solutions, t.solutions)
            for key, p in o.problems.items():
                _keep_vectors(p.solutions, t.problems[key].solutions)
    return typed


def _keep_vectors(solutions: Sequence[Solution], typed: Sequence[MceipSolution]) -> None:
    for s, t in zip(solutions, typed):
        if s.x is not None:
            t.x = s.x
