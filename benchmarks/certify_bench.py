"""Benchmark: proving MCEIP-mu (app/analyses/mceip_mu/state.py) against exhaustive enumeration.

For random systems and block states with s slip nodes: the time to certify the onset and every
critical mu up to the cap (dense search + certificate, as the app runs it), the time of
exhaustive enumeration of all 2^s - 1 supports where it runs, the search's recall against the
certified set, and which certificate was used. Ratios are measured in one run (the machine is
shared: absolute times are noisy).

    .venv/bin/python benchmarks/certify_bench.py [--s 8,12,16,20,30,60,120] [--enum-max 16]
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402


def say(*a) -> None:
    print(*a, flush=True)


def _random_pencil(s: int, seed: int):
    from app.analyses.pencils.reduced import condensed_mu_pencil
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.systems.discrete import random_contact_problem
    rng = np.random.default_rng(seed)
    mu = float(rng.uniform(0.5, 3.0))
    system, state = random_contact_problem(rng, s + 2, 4, s, 1, mu, MPI.COMM_WORLD, Stages())
    A0, A1 = condensed_mu_pencil(system.contact_schur(), classify(state, mu))
    system.destroy()
    return A0, A1, mu


def _block_pencils(s_values: list[int]) -> dict:
    """Block states (paper loading, crossed P1) with the slip-node count nearest each target."""
    from benchmarks.problems import block_problems
    out, pool = {}, []
    for nx in (20, 40, 80):          # s up to about 17, 35, 70 (nx = 160 would take minutes of path)
        if nx > 20 and max(s_values) <= (nx // 2) * 17 // 20:
            break
        probs = block_problems(nx=nx)
        pool += [(p.A0.shape[0], nx, p) for p in probs.pencils]
    for nx in sorted({q[1] for q in pool}):       # the final state of each mesh (onset below the cap)
        s_fin, _, p_fin = [q for q in pool if q[1] == nx][-1]
        out[f"final{nx}"] = (s_fin, nx, p_fin)
    for s in s_values:
        best = min(pool, key=lambda q: (abs(q[0] - s), -q[0]))
        if abs(best[0] - s) <= max(2, 0.15 * s):
            out[s] = best
    return out


def _one(kind: str, A0: np.ndarray, A1: np.ndarray, mu: float, enum_max: int, budget: float) -> dict:
    from app.analyses.enumerate import enumerate_patterns
    from app.analyses.mceip_mu.state import condensed_mu_result, mu_cap
    from app.linalg import one_blas_thread
    from app.scene.schema import McpSettings
    settings = McpSettings(certify_seconds=budget)
    cap = mu_cap(mu, settings)
    s = A0.shape[0]
    t0 = time.perf_counter()
    d = condensed_mu_result(A0, A1, cap, settings)
    t_cert = time.perf_counter() - t0
    below = [x for x in d["solutions"] if x["value"] <= cap]
    found = sum(1 for x in below if any(not f.startswith("certificate") for f in x["found_by"]))
    row = {"s": s, "kind": kind, "cap": cap, "certified": d["certified"], "method": d["certificate"]["method"],
           "status": d["certificate"]["status"], "n_below_cap": len(below), "search_found": found,
           "onset": below[0]["value"] if below else None, "t_certify": t_cert,
           "t_search": d["search"]["seconds"], "t_certificate": d["certificate"]["seconds"]}
    if s <= enum_max:
        t0 = time.perf_counter()
        with one_blas_thread():
            ref = enumerate_patterns(A0, A1, np.arange(s), t_max=cap)
        row["t_enum"] = time.perf_counter() - t0
        got = sorted((round(x["value"], 7), tuple(x["pattern"])) for x in below)
        exp = sorted((round(p.value, 7), tuple("slip" if b else "stick" for b in p.support)) for p in ref)
        row["agrees_with_enumeration"] = got == exp
    return row


def section_certify(s_values: list[int], enum_max: int = 16, budget: float = 60.0, seed: int = 5) -> dict:
    say(f"\n== Certified MCEIP-mu (onset and every mu <= cap = 10 x scene mu) vs exhaustive enumeration, "
        f"s = {s_values[0]}..{s_values[-1]} ==")
    say(f"{'s':>4} {'problem':>7} {'certificate':>24} {'status':>22} {'<=cap':>5} {'recall':>7} {'onset':>10} "
        f"{'t_cert[s]':>9} {'t_enum[s]':>9} {'enum/cert':>9} {'same':>5}")
    rows = []
    blocks = _block_pencils(s_values)
    for s in s_values:
        cases = []
        A0, A1, mu = _random_pencil(s, seed + s)
        cases.append(("random", A0, A1, mu))
        if s in blocks:
            sb, nx, p = blocks[s]
            cases.append((f"block{nx}", p.A0, p.A1, 1.1))
        cases += [(f"fin{nx}", p.A0, p.A1, 1.1) for key, (sf, nx, p) in blocks.items()
                  if str(key).startswith("final") and s_values.index(s) == min(
                      range(len(s_values)), key=lambda i: abs(s_values[i] - sf))]
        for kind, A0, A1, mu in cases:
            r = _one(kind, A0, A1, mu, enum_max, budget)
            rows.append(r)
            rec = f"{r['search_found']}/{r['n_below_cap']}"
            te = r.get("t_enum")
            onset = "-" if r["onset"] is None else f"{r['onset']:.6g}"
            tes = "-" if te is None else f"{te:.3f}"
            ratio = "-" if te is None else f"{te / r['t_certify']:.1f}"
            same = str(r.get("agrees_with_enumeration", "-"))
            say(f"{r['s']:>4} {kind:>7} {r['method'][:24]:>24} {r['status'][:22]:>22} {r['n_below_cap']:>5} {rec:>7} "
                f"{onset:>10} {r['t_certify']:>9.3f} {tes:>9} {ratio:>9} {same:>5}")
    largest = {k: max((r["s"] for r in rows if r["kind"].startswith(k) and r["certified"] and r["t_certify"] <= 60),
                      default=None) for k in ("random", "block", "fin")}
    at60 = [r for r in rows if 55 <= r["s"] <= 65]
    say(f"largest s certified within a minute (random, block, block final state): {largest}; at s ~ 60: "
        + ", ".join(f"{r['kind']} {r['t_certify']:.2f} s ({r['status']})" for r in at60))
    say(f"search recall against the certified sets: {sum(r['search_found'] for r in rows if r['certified'])} of "
        f"{sum(r['n_below_cap'] for r in rows if r['certified'])}; certified = enumeration wherever both ran: "
        f"{all(r.get('agrees_with_enumeration', True) for r in rows)}")
    return {"rows": rows, "largest_s_within_60s": largest}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--s", default="8,12,16,20,30,60,120")
    ap.add_argument("--enum-max", type=int, default=16)
    ap.add_argument("--budget", type=float, default=60.0)
    args = ap.parse_args()
    section_certify([int(x) for x in args.s.split(",")], args.enum_max, args.budget)


if __name__ == "__main__":
    main()
