"""Soundness of the quadratic MCEIP-mu branch and bound (curved obstacles, docs/curved.md).

Random pencils ``A(mu) = A0 + mu A1 + mu^2 A2`` (``A0`` SPD plus the diagonal ``A2 = G`` of either
sign or zero, as kappa P), s = 1-10, caps 10 and 30, some near-degenerate (two identical nodes to
1e-9, ``A2`` at 1e-13 of ``A0``). The reference is the exhaustive exact per-support proof
(``prove_quadratic``: every one of the 2^s supports decided in rational and ball arithmetic). A
*false proof* is a claim of the branch and bound (the list complete, or the onset) that the
reference contradicts: another set of supports, or enclosures that do not meet. Pencils where the
reference leaves a support undecided have no known truth and are counted apart.

``--pairs``: split pencils of zero-reaction nodes instead (app/analyses/pencils/curved_split.py's
construction on a random SPD contact Schur complement: 1-3 slip nodes with ``G``, 1-2 zero nodes
with their pairs ``(a, b)``), proven by both with the pairs.

    .venv/bin/python benchmarks/soundness_quadratic.py [--n 300] [--start 0] [--pairs]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.analyses.mceip_mu.quadratic.bb import prove_bb  # noqa: E402
from app.analyses.mceip_mu.quadratic.proof import prove_quadratic  # noqa: E402

KINDS = ("plain", "twin nodes", "tiny A2")


def pencil(k: int):
    """Pencil number ``k``: (A0, A1, A2, cap, s, kind)."""
    rng = np.random.default_rng(90_000 + k)
    s = int(rng.integers(1, 11))
    kind = KINDS[k % len(KINDS)] if s > 1 else "plain"
    B = rng.normal(size=(s, s))
    A0 = B @ B.T + s * np.eye(s)
    A1 = rng.normal(size=(s, s)) * 1.5
    G = np.diag(float(rng.choice([-1.5, -0.5, 0.4, 1.2])) * rng.uniform(0.2, 1.0, size=s))
    if kind == "twin nodes":        # node 1 a copy of node 0 to 1e-9
        for A in (A0, A1, G):
            A[1, :], A[:, 1] = A[0, :] * (1 + 1e-9), A[:, 0] * (1 + 1e-9)
            A[1, 1] = A[0, 0] * (1 + 2e-9)
        A0 += 1e-6 * np.eye(s)
    elif kind == "tiny A2":
        G = G * 1e-13 * np.max(np.abs(A0))
    return A0 + G, A1, G, float(rng.choice([10.0, 30.0])), s, kind


def pencil_with_pairs(k: int):
    """Split pencil number ``k`` with zero-reaction nodes: (A0, A1, A2, cap, s, kind, pairs)."""
    from app.analyses.pencils.reduced import split_pencil
    from app.loading.classify import Classification
    rng = np.random.default_rng(70_000 + k)
    ns, nz = int(rng.integers(1, 4)), int(rng.integers(1, 3))
    n = ns + nz
    B = rng.normal(size=(2 * n, 2 * n))
    cls = Classification(tuple(["slip"] * ns + ["zero"] * nz),
                         tuple(int(v) for v in rng.choice([-1, 1], ns)) + (0,) * nz)
    sp = split_pencil(B @ B.T + 0.3 * np.eye(2 * n), 2 * np.arange(n), 2 * np.arange(n) + 1, np.ones(n), np.ones(n),
                      cls, np.array([], dtype=int))
    G = np.zeros_like(sp.A0)
    G[np.arange(ns), np.arange(ns)] = float(rng.choice([-1.5, -0.5, 0.4, 1.2])) * rng.uniform(0.2, 1.0, size=ns)
    return sp.A0 + G, sp.A1, G, float(rng.choice([10.0, 30.0])), ns + 3 * nz, f"{ns} slip, {nz} zero", sp.pairs


def _meet(x, y) -> bool:
    return x.enclosure[0] <= y.enclosure[1] and y.enclosure[0] <= x.enclosure[1]


def classify(b, e) -> str:
    """``agree``, ``FALSE``, ``not proven`` (the branch and bound claims nothing contradicted)
    or ``unknown truth`` (the reference undecided)."""
    if not e.proven:
        return "unknown truth"
    false = False
    if b.proven:
        same = [p.support for p in b.solutions] == [p.support for p in e.solutions]
        false |= not (same and all(_meet(x, y) for x, y in zip(b.solutions, e.solutions)))
    if b.onset_proven:
        bo, eo = b.onset, e.onset
        false |= (bo is None) != (eo is None) or (bo is not None and (bo.support != eo.support or not _meet(bo, eo)))
    if false:
        return "FALSE"
    return "agree" if b.proven else "not proven"


def section_quadratic(n: int = 300, start: int = 0, say=print, pairs: bool = False) -> dict:
    """The figures of ``n`` pencils from ``start`` (``pairs``: split pencils of zero-reaction
    nodes): verdict counts, critical values, seconds."""
    counts: dict[str, int] = {}
    t_bb = t_ref = 0.0
    n_sol = 0
    false = []
    for k in range(start, start + n):
        A0, A1, A2, cap, s, kind, prs = pencil_with_pairs(k) if pairs else (*pencil(k), [])
        t0 = time.perf_counter()
        b = prove_bb(A0, A1, A2, cap, deadline=time.perf_counter() + 60.0, pairs=prs)
        t1 = time.perf_counter()
        e = prove_quadratic(A0, A1, A2, cap, max_s=12, pairs=prs)
        t_bb, t_ref = t_bb + t1 - t0, t_ref + time.perf_counter() - t1
        verdict = classify(b, e)
        counts[verdict] = counts.get(verdict, 0) + 1
        n_sol += len(e.solutions) if e.proven else 0
        if verdict == "FALSE":
            false.append(k)
            say(f"FALSE PROOF: pencil {k} (s = {s}, {kind}, cap {cap})")
    out = {"pencils": n, "start": start, "pairs": pairs, "false_proofs": counts.get("FALSE", 0),
           "false_pencils": false, "agree": counts.get("agree", 0), "critical_values": n_sol,
           "not_proven": counts.get("not proven", 0), "unknown_truth": counts.get("unknown truth", 0),
           "bb_s": t_bb, "reference_s": t_ref}
    say(describe(out))
    return out


def describe(r: dict) -> str:
    """One line of the section's figures (``make bench``'s summary prints it too)."""
    what = "split pencils with pairs, s = 4-9" if r.get("pairs") else f"s = 1-10; {', '.join(KINDS)}"
    return (f"quadratic soundness: {r['pencils']} pencils ({what}): FALSE PROOFS "
            f"{r['false_proofs']}; agree {r['agree']} ({r['critical_values']} critical values), "
            f"not proven {r['not_proven']}, reference undecided {r['unknown_truth']}; "
            f"branch and bound {r['bb_s']:.1f} s, per-support proof {r['reference_s']:.1f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--pairs", action="store_true", help="split pencils of zero-reaction nodes, with pairs")
    args = ap.parse_args(argv)
    r = section_quadratic(args.n, args.start, say=lambda *a: print(*a, flush=True), pairs=args.pairs)
    return 1 if r["false_proofs"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
