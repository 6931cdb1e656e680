"""The soundness benchmark's ground truth (benchmarks/soundness.py) and its judge.

The truth must agree with the app's floating-point enumeration where that is clean, find every
planted near-degenerate solution (and reject the planted near-misses), and catch the false
"proven, no solution" of the seed-394604 pencil of tests/test_certify.py.
"""
import numpy as np
import pytest
from mpi4py import MPI

from app.analyses.enumerate import enumerate_patterns
from app.analyses.pencils.reduced import condensed_mu_pencil
from app.common.stages import Stages
from app.loading.classify import classify
from app.systems.discrete import random_contact_problem
from benchmarks.soundness import Truth, ground_truth, judge, make_pencil


def _key(values):
    return [round(v, 7) for v in values]


@pytest.mark.parametrize("kind", ["dense", "condensed", "sparse", "zero", "contact"])
def test_truth_agrees_with_enumeration_on_clean_pencils(kind):
    checked = 0
    for i in range(40):
        p = make_pencil(i, kind=kind)
        s = p.A0.shape[0]
        ref = enumerate_patterns(p.A0, p.A1, np.arange(s), 0.0, p.cap, pairs=p.pairs)
        if any(r.ill_conditioned for r in ref):
            continue
        tr = ground_truth(p.A0, p.A1, p.cap, p.pairs)
        assert tr.known, tr.reasons
        got = sorted((round(mu, 7), sup) for mu, sup, _ in tr.solutions)
        exp = sorted((round(r.value, 7), tuple(np.flatnonzero(r.support).tolist())) for r in ref)
        assert got == exp, (i, kind)
        checked += 1
        if checked == 6:
            break
    assert checked == 6


@pytest.mark.parametrize("kind", ["interior", "close", "double", "at_cap", "at_zero", "small_x", "small_y", "miss_x",
                                  "miss_y"])
def test_planted_solutions_are_found(kind):
    n = 0
    for i in range(8):
        p = make_pencil(i, kind=kind, s=2 + i % 6)
        tr = ground_truth(p.A0, p.A1, p.cap, p.pairs)
        assert tr.known, tr.reasons
        # "double": its two roots are 1e-11..1e-9 apart, the planted one off by rounding only
        rtol = 1e-13 if kind == "double" else 1e-9
        for pl in p.planted:
            hit = [m for mu, sup, m in tr.solutions if sup == pl["support"]
                   and abs(mu - pl["mu"]) <= rtol * max(1.0, pl["mu"])]
            assert bool(hit) == pl["solution"], (i, pl)
            if kind in ("at_cap", "at_zero"):
                assert pl["exact"]
                # exactly at the interval's end, decided in exact arithmetic
                assert pl["mu"] in [mu for mu, sup, _ in tr.solutions if sup == pl["support"]]
                assert hit == ["exact"]
            n += 1
        if kind == "close":
            a, b = sorted(pl["mu"] for pl in p.planted)
            assert 0 < b - a <= 1e-9
            # both listed, as two values (the planted columns are rounded: mu within 1e-13)
            near = [[v for v in tr.values if abs(v - m) <= 1e-13 * max(1.0, m)] for m in (a, b)]
            assert len(near[0]) == 1 and len(near[1]) == 1 and near[0] != near[1]
        if kind in ("small_x", "small_y", "miss_x", "miss_y", "double"):
            assert tr.exact_supports > 0          # the tiny margin went to exact arithmetic
        if kind == "double":
            assert [m for mu, sup, m in tr.solutions if sup == p.planted[0]["support"]] == ["exact"]
    assert n >= 8


def test_floating_step_agrees_with_exact_on_every_support():
    """The truth's clear floating decisions against exact/ball arithmetic on every support."""
    kinds = ["dense", "condensed", "sparse", "zero", "interior", "close", "double", "small_x", "miss_y"]
    for i, kind in enumerate(kinds):
        p = make_pencil(100 + i, kind=kind, s=3 + i % 3)
        a = ground_truth(p.A0, p.A1, p.cap, p.pairs)
        b = ground_truth(p.A0, p.A1, p.cap, p.pairs, exact_all=True)
        assert a.known and b.known
        assert [(round(m, 9), sup) for m, sup, _ in a.solutions] == [(round(m, 9), sup) for m, sup, _ in b.solutions]


def test_seed_394604_false_proof_is_caught():
    """tests/test_certify.py's explicit example: SCIP said "proven, no solution" on this pencil."""
    rng = np.random.default_rng(394604)
    system, state = random_contact_problem(rng, 4 + 2 + 1, 1, 4, 2, 1.0, MPI.COMM_WORLD, Stages())
    A0, A1 = condensed_mu_pencil(system.contact_schur(), classify(state, 1.0))
    system.destroy()
    tr = ground_truth(A0, A1, 8.5)
    assert tr.known
    # support: the first slip unknown alone (the "node 1", y = (0, 0.726, 0.430, 0.879))
    assert (4.733117, (0,)) in [(round(mu, 6), sup) for mu, sup, _ in tr.solutions]
    j = judge(tr, "proven", None, "proven", [])
    assert j["onset_false"] and j["all_false"]
    ok = judge(tr, "proven", tr.onset, "proven", list(tr.values))
    assert not ok["onset_false"] and not ok["all_false"]
    assert judge(tr, "not proven", None, "ill-conditioned", [])["all_false"] is None


def test_judge_tolerances_and_optional_values():
    tr = Truth(True, [1.0, 1.0 + 5e-10, 3.0], [5.0000001], [])
    assert not judge(tr, "proven", 1.0 + 5e-8, "proven", [1.0, 3.0 + 1e-7])["all_false"]
    assert judge(tr, "proven", 1.0 + 5e-7, "proven", [1.0])["all_false"]          # 3.0 missing
    assert judge(tr, "proven", 1.0, "proven", [1.0, 2.0, 3.0])["all_false"]       # 2.0 is not a value
    assert not judge(tr, "proven", 1.0, "proven", [1.0, 3.0, 5.0])["all_false"]   # just above the cap: optional
    assert judge(tr, "proven", 1.0 + 5e-7, "not proven", [])["onset_false"]
    assert judge(Truth(False, [], [], []), "proven", None, "proven", [])["onset_false"] is None


def test_pencils_are_reproducible():
    for i in (0, 7, 123):
        a, b = make_pencil(i), make_pencil(i)
        assert a.kind == b.kind and a.cap == b.cap and a.pairs == b.pairs
        assert np.array_equal(a.A0, b.A0) and np.array_equal(a.A1, b.A1)


def test_adapters_read_the_new_engine_api(monkeypatch):
    """The ``mceip_mu`` adapter maps ``app.mceip_mu``'s result (a stand-in here) to the statuses."""
    from types import SimpleNamespace

    import app
    from benchmarks.soundness import get_prover

    def fake(A0, A1, cap, pairs=None):
        return SimpleNamespace(onset=SimpleNamespace(proven=True, value=1.5),
                               all=SimpleNamespace(proven=False, values=[2.0, 1.5]), ill_conditioned=False)

    monkeypatch.setattr(app, "mceip_mu", fake, raising=False)
    name, prove = get_prover("auto")
    assert name == "mceip_mu"
    assert prove(np.eye(2), np.eye(2), 3.0, []) == ("proven", 1.5, "not proven", [1.5, 2.0])
    monkeypatch.setattr(app, "mceip_mu", lambda *a, **k: SimpleNamespace(
        onset=SimpleNamespace(proven=True, value=None), all=SimpleNamespace(proven=True, values=[]),
        ill_conditioned=True), raising=False)
    assert prove(np.eye(2), np.eye(2), 3.0, []) == ("ill-conditioned", None, "ill-conditioned", [])
