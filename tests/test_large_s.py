"""The large-s path of the condensed MCEIP-mu (issue 14: 100k-DOF studies, s up to ~180).

Above ``mcp.search_full_max`` slip nodes the dense search runs a reduced start set plus warm
starts from the previous classification of a chain, and the onset proof gets ``certify_onset_nodes_large``.
Forced here on small problems (``search_full_max = 0``) so that enumeration can check it.
"""
import json

import numpy as np
import pytest
from conftest import run_cli, run_cli_here

from app.analyses.enumerate import enumerate_patterns
from app.analyses.mceip_mu import candidates
from app.analyses.mceip_mu.state import condensed_mu_result
from app.scene.schema import McpSettings
from app.study.scheduler import _chain_order, _chains


@pytest.fixture(scope="module")
def pencils():
    from benchmarks.problems import block_problems
    return [p for p in block_problems(nx=20).pencils if p.A0.shape[0] >= 6]


def _exact(c, ref) -> bool:
    return any(abs(c.exact.value - r.value) <= 1e-8 * max(1.0, r.value) and np.array_equal(c.exact.support, r.support)
               for r in ref)


def test_reduced_search_finds_only_exact_solutions_and_the_onset(pencils):
    """Every candidate of the reduced search is an exact solution (25)-(26) listed by enumeration,
    and at the final (all-slip) state it finds the smallest solution, as the full search does."""
    checked = 0
    for p in pencils:
        s = p.A0.shape[0]
        if s > 12:                                           # enumeration of 2^s supports: small s only
            continue
        rep = candidates.search(p.A0, p.A1, full_max=0, one_node=4)
        assert rep.starts < (s + 1) * 5                      # fewer runs than the full start set
        assert "reduced start set" in rep.note
        ref = enumerate_patterns(p.A0, p.A1, np.arange(s))
        assert all(_exact(c, ref) for c in rep.candidates), p.label
        checked += len(rep.candidates)
    assert checked
    last = pencils[-1]
    full = candidates.search(last.A0, last.A1)
    rep = candidates.search(last.A0, last.A1, full_max=0, one_node=4)
    assert full.candidates and rep.candidates
    assert rep.candidates[0].exact.value == pytest.approx(full.candidates[0].exact.value, rel=1e-10)


def test_warm_start_from_a_solution_converges_at_once(pencils):
    """A warm start at an exact solution (the previous classification's, mapped) is reported as
    found by that start, in at most two Newton iterations."""
    p = pencils[-1]
    s = p.A0.shape[0]
    ref = [c.exact for c in candidates.search(p.A0, p.A1).candidates]       # the full search's solutions
    assert ref
    warm = [(r.x[np.arange(s)], r.value) for r in ref]
    rep = candidates.search(p.A0, p.A1, full_max=0, one_node=2, mu0s=(1000.0,), warm=warm)
    for r in ref:
        hit = [c for c in rep.candidates if abs(c.exact.value - r.value) <= 1e-8 * max(1, r.value)]
        assert hit, r.value
        runs = [f for f in hit[0].found_by if "previous classification" in f]
        assert runs and all(int(f.split("(")[-1].split(" ")[0]) <= 2 for f in runs), hit[0].found_by


def test_large_budget_is_used_and_labelled(pencils):
    """With ``certify_onset_nodes_large = 0`` the proof gets no tree nodes above ``search_full_max``:
    a state is certified only when the sign argument alone closes [0, cap] (done before any budget
    check), otherwise it says "not proven within budget" (never "stopped by the time limit": no
    time limit is set) and certifies no solution."""
    st = McpSettings(search_full_max=0, certify_onset_nodes_large=0, certify_enumerate_max=0)
    seen_unproven = False
    for p in pencils:
        d = condensed_mu_result(p.A0, p.A1, 11.0, st)
        if d.certified:
            assert not [x for x in d.solutions if x.value <= 11.0]
            continue
        seen_unproven = True
        assert d.certificate.status in ("not proven within budget", "ill-conditioned")
        assert "not proven" in d.result or "ill-conditioned" in d.result
        assert all(not x.certified for x in d.solutions)
    assert seen_unproven


def test_chains_and_their_order():
    s = [1, 2, 3, 5, 8, 13, 40, 90, 120, 150, 170, 180, 180, 181, 179, 30, 60]
    chains = _chains(s, 4, 40)
    assert chains == [[0], [1], [2], [3], [4], [5], [6], [7, 8, 9, 10], [11, 12, 13, 14], [15], [16]]
    order = _chain_order(s, chains)
    assert sorted(order) == list(range(len(chains)))          # every chain once
    cost = [sum((s[k] + 1) ** 3 for k in chains[c]) for c in order]
    assert cost == sorted(cost, reverse=True)


SCENE = """\
name: large-s-check
system: {type: block, nx: 16, ny: 8}
mu: 1.1
analyses: [mceip_mu]
settings: {mcp: {search_full_max: 3, warm_chain: 3, certify_onset_nodes_large: 0, certify_enumerate_max: 3,
                  prove_first: false}}
"""


@pytest.mark.mpi
@pytest.mark.slow
def test_large_path_same_answers_on_one_and_two_ranks(tmp_path):
    """The chains of warm-started classifications do not depend on the number of ranks."""
    (tmp_path / "s.yaml").write_text(SCENE)
    out = {}
    for ranks in (1, 2):
        args = ("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / f"o{ranks}"), "-q")
        p = run_cli_here(*args) if ranks == 1 else run_cli(*args, ranks=ranks)      # 1 rank: in this process
        assert p.returncode == 0, p.stderr
        res = json.loads((tmp_path / f"o{ranks}" / "results.json").read_text())
        out[ranks] = [(a["mceip_mu"].get("certified"), a["mceip_mu"].get("certificate", {}).get("status"),
                       [(x["value"], tuple(x["pattern"])) for x in a["mceip_mu"]["solutions"]])
                      for a in (s["analyses"] for s in res["states"])]
    assert any("previous classification" in f for s in res["states"]
               for x in s["analyses"]["mceip_mu"]["solutions"] for f in x.get("found_by", []))
    assert len(out[1]) == len(out[2])
    for a, b in zip(out[1], out[2]):
        assert a[:2] == b[:2]
        assert [pat for _, pat in a[2]] == [pat for _, pat in b[2]]
        assert [v for v, _ in a[2]] == pytest.approx([v for v, _ in b[2]], rel=1e-8)
