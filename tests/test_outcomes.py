"""The typed outcomes of the analyses (app/analyses/outcomes.py): each type's results.json entry
reads back through the typed reader (app/io/result.py) with the same values, also through a JSON
file (non-finite numbers included), and a failing solver gives a ``Failed`` with a one-line reason."""
import json
import math

import numpy as np
from mpi4py import MPI

from app.analyses import runner
from app.analyses.outcomes import (
    Certificate,
    CompleteClaim,
    Deferred,
    EnumerationOutcome,
    EnumerationProblem,
    Failed,
    MceipLambda2Outcome,
    MceipMuOutcome,
    NecessaryOutcome,
    NotApplicable,
    OnsetClaim,
    Solution,
    SufficientOutcome,
    analyses_document,
)
from app.common.stages import Stages
from app.io.document import from_document, json_clean, to_document
from app.io.result import StateResult, StudyResult
from app.loading.classify import classify
from app.scene.schema import parse_scene
from app.systems.discrete import random_contact_problem


def _solution(value: float, certified: bool | None = True) -> Solution:
    ev = {"residual": 1e-12, "complementarity": 0.0, "found_by": ["test"], "found_count": 1, "iterations": 3}
    if certified is not None:
        ev["certified"] = certified
    return Solution(value=value, x_Ts=[0.25, 0.75], pattern=["slip", "slip"], evidence=ev,
                    x=np.array([1.0, 2.0, 3.0]))


def _outcomes() -> dict:
    cert = Certificate("exhaustive enumeration (24)-(26), batched LAPACK", (0.0, math.inf), "proven", gap=0.0,
                       detail={"solutions": 1})
    mu_cert = Certificate("branch and bound", (0.0, 20.0), "proven", gap=0.0, seconds=0.5, detail={"s": 2},
                          cap=20.0, onset=1.7048)
    return {
        "necessary": NecessaryOutcome(mu=2.0, min_eig_K_sym=-3.0, min_eig_K_sym_relative=-0.1, min_eig_M_sym=1.0,
                                      min_eig_M_sym_relative=0.5, satisfied=True),
        "sufficient": SufficientOutcome(satisfied=True, lambda2=[4.0e6], modes=[_solution(4.0e6, None)],
                                        real_candidates=[{"lambda2": 4.0e6, "admissible": True, "min_x_Ts_rel": 0.3,
                                                          "relative_error": 1e-13}],
                                        eigensolver="SLEPc lapack, all 2 eigenvalues", converged=2, mu=2.0),
        "mceip_mu": MceipMuOutcome(solutions=[_solution(1.7048), _solution(60.8, False)], result="proven onset",
                                   search={"complete": True, "intervals": ["[0, inf)"]}, certified=True,
                                   certificate=mu_cert,
                                   onset=OnsetClaim(True, "proven", 1.7048, [1.70479, 1.70481]),
                                   complete=CompleteClaim(True, "proven", [0.0, 20.0], 1), method="condensed",
                                   proof={"A0": np.eye(2)}),
        "mceip_lambda2": MceipLambda2Outcome(solutions=[_solution(1.9e6, False)], result="1 distinct solution(s) found",
                                             search={"complete": False, "lambda2_upper_bound": math.inf},
                                             certified=False,
                                             certificate=Certificate("none", (0.0, 0.0), "not proven", seconds=0.1),
                                             mu=2.0),
        "enumerate": EnumerationOutcome(problems={
            "mu": EnumerationProblem("mu", [_solution(1.7048)], True, certified=True, certificate=cert),
            "lambda2": EnumerationProblem("lambda2", [], False, certified=False, refused="too many slip nodes")},
            first="mu"),
    }


def _study(states: list) -> dict:
    """A study's results around ``states``, with the keys every run writes."""
    return {"scene": "t", "units": {"length": "mm", "force": "N", "lambda2": "1/s^2", "mu": "1"}, "system": "test",
            "mu": 2.0, "analyses_requested": [], "path": {"end": "test"}, "distinct_classifications": 1,
            "stages": [], "failures": [], "warnings": [], "mpi_ranks": 1, "wall_seconds": 0.0, "scene_config": {},
            "states": states}


def _read_back(analyses: dict) -> StateResult:
    """The state's analyses through results.json: document, JSON text, reader."""
    entry = {"index": 0, "load": {}, "classification": {"free": 0, "zero": 0, "stick": 0, "slip": 2}, "nodes": [],
             "analyses_shared_with": None, "analyses": analyses_document(analyses)}
    text = json.dumps(to_document(_study([entry])), allow_nan=False)
    study = StudyResult.from_dict(from_document(json.loads(text)))
    return study.states[0]


def test_every_outcome_type_round_trips_through_the_typed_reader():
    out = _outcomes()
    st = _read_back(out)
    nec, suf = out["necessary"], out["sufficient"]
    assert (st.necessary.satisfied, st.necessary.min_eig_K_sym, st.necessary.min_eig_M_sym) == \
        (nec.satisfied, nec.min_eig_K_sym, nec.min_eig_M_sym)
    assert list(st.sufficient.lambda2) == suf.lambda2 and st.sufficient.satisfied
    assert [m.value for m in st.sufficient.modes] == [m.value for m in suf.modes]
    assert list(st.sufficient.modes[0].x_Ts) == suf.modes[0].x_Ts
    mu = out["mceip_mu"]
    assert [s.value for s in st.mceip_mu.solutions] == [s.value for s in mu.solutions]
    assert [s.certified for s in st.mceip_mu.solutions] == [True, False]
    assert st.mceip_mu.certified is True and st.mceip_mu.method == "condensed"
    assert st.mceip_mu.certificate.to_dict() == mu.certificate.as_dict()
    assert st.mceip_mu.onset.to_dict() == mu.onset.as_dict() and st.mceip_mu.complete.to_dict() == mu.complete.as_dict()
    # what stays in memory is never in the file: read back, there is none
    assert st.mceip_mu.proof is None and all(s.x is None for s in st.mceip_mu.solutions)
    assert "proof" not in st.mceip_mu.to_dict() and all("x" not in s.to_dict() for s in st.mceip_mu.solutions)
    assert st.min_mu() == 1.7048
    l2 = out["mceip_lambda2"]
    assert st.mceip_lambda2.mu == l2.mu and st.mceip_lambda2.certified is False
    assert st.mceip_lambda2.search["lambda2_upper_bound"] == math.inf        # null in the file, inf again
    assert st.mceip_lambda2.solutions[0].pattern == tuple(l2.solutions[0].pattern)
    assert st.enumerate.problem == "mu" and [s.value for s in st.enumerate.solutions] == [1.7048]
    assert st.enumerate.certificate.interval == [0.0, math.inf]
    assert st.enumerate.problems["lambda2"].model_extra["refused"] == "too many slip nodes"
    # every entry reads back exactly as written, every key and value
    for name, a in out.items():
        assert json_clean(getattr(st.analyses, name).to_dict()) == json_clean(a.as_dict()), name
    assert st.failed == {}


def test_failed_and_not_applicable_entries():
    st = _read_back({"necessary": Failed("RuntimeError: SLEPc did not converge"),
                     "sufficient": NotApplicable("not applicable: frictionless"),
                     "mceip_mu": _outcomes()["mceip_mu"]})
    assert st.failed == {"necessary": "RuntimeError: SLEPc did not converge"}
    assert st.necessary is None and st.sufficient is None and st.mceip_mu is not None
    assert Failed("x").as_dict() == {"failed": True, "reason": "x"}
    assert NotApplicable("y").as_dict() == {"not_applicable": True, "reason": "y"}
    assert Deferred().as_dict() == {"deferred": True}


def _scene(mu, analyses):
    return parse_scene({"name": "random", "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30,
                                                       "signs": [1, 1]}, "mu": mu, "analyses": analyses})


def test_a_failing_solver_is_a_failed_outcome_with_a_one_line_reason(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("SLEPc did not converge the smallest eigenvalue\n(second line of the message)")

    monkeypatch.setattr(runner, "_necessary", broken)
    system, state = random_contact_problem(np.random.default_rng(3), 6, 4, 3, 1, 2.0, MPI.COMM_WORLD, Stages())
    try:
        out = runner.analyse_state(system, classify(state, 2.0), _scene(2.0, ["necessary", "sufficient"]))
    finally:
        system.destroy()
    assert isinstance(out["necessary"], Failed)
    assert out["necessary"].reason == "RuntimeError: SLEPc did not converge the smallest eigenvalue"
    assert "\n" not in out["necessary"].reason
    assert isinstance(out["sufficient"], SufficientOutcome)          # the other analyses still run
    assert list(out) == ["necessary", "sufficient"]


def test_analyses_of_a_state_are_typed():
    """A real state's MCEIP-mu and enumeration are typed and read back with the same values."""
    analyses = ["mceip_mu", "enumerate"]
    system, state = random_contact_problem(np.random.default_rng(4), 6, 4, 3, 1, 2.0, MPI.COMM_WORLD, Stages())
    try:
        out = runner.analyse_state(system, classify(state, 2.0), _scene(2.0, analyses))
    finally:
        system.destroy()
    assert isinstance(out["mceip_mu"], MceipMuOutcome) and isinstance(out["mceip_mu"].certificate, Certificate)
    assert len(out["mceip_mu"].solutions) == 2 and all(isinstance(s, Solution) for s in out["mceip_mu"].solutions)
    assert isinstance(out["enumerate"], EnumerationOutcome)
    st = _read_back(out)
    assert list(st.mu_values()) == sorted(s.value for s in out["mceip_mu"].solutions)
    assert st.mceip_mu.certified == out["mceip_mu"].certified
    assert [s.value for s in st.enumerate.solutions] == [s.value for s in out["enumerate"].problems["mu"].solutions]
