"""What fraction of the enumerated solutions does the SNES VI MCP search find?

Random small systems (s = 1..6 slip nodes, some stick and free nodes, interior DOFs): for each,
the exhaustive enumeration (exact, complete) gives the solution set of MCEIP-mu and of
MCEIP-lambda^2; the MCP search runs independently. Prints, per s, the number of enumerated
distinct solutions, the fraction found, spurious solutions (must be 0) and timings.

    .venv/bin/python benchmarks/mcp_coverage.py [--cases 20] [--max-slip 6]
"""
from __future__ import annotations

import argparse
import platform

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.analyses.runner import analyse_state
from app.common.stages import Stages
from app.loading.classify import classify
from app.scene.schema import parse_scene
from app.systems.discrete import random_contact_problem


def _match(sol, ref):
    return (abs(sol["value"] - ref["value"]) <= 1e-6 * max(1.0, abs(ref["value"]))
            and sol["pattern"] == ref["pattern"] and np.allclose(sol["x_Ts"], ref["x_Ts"], atol=1e-5))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--max-slip", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print(f"machine: {platform.machine()} {platform.processor() or ''}, python {platform.python_version()}, "
          f"PETSc {'.'.join(map(str, PETSc.Sys.getVersion()))}")
    rng = np.random.default_rng(args.seed)
    print(f"{'s':>3} {'problem':>8} {'enumerated':>10} {'found':>6} {'fraction':>8} {'spurious':>8} "
          f"{'t_mcp[s]':>9} {'t_enum[s]':>9}")
    total_ref = total_found = total_spurious = 0
    for s in range(1, args.max_slip + 1):
        agg = {p: [0, 0, 0, 0.0, 0.0] for p in ("mu", "lambda2")}
        for _ in range(args.cases):
            mu = float(rng.uniform(0.3, 4.0))
            stages = Stages()
            system, state = random_contact_problem(rng, s + 3, 6, s, int(rng.integers(0, 3)), mu, MPI.COMM_WORLD, stages)
            scene = parse_scene({"name": "cov", "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30,
                                                             "signs": [1, 1]}, "mu": mu,
                                 "analyses": ["mceip_mu", "mceip_lambda2", "enumerate"],
                                 "settings": {"enumerate_max_slip": 16}})
            a = analyse_state(system, classify(state, mu), scene)
            rec = {r["name"]: r["seconds"] for r in stages.as_list()}
            for prob, key, stage in (("mu", "mceip_mu", "MCEIP-mu (21)-(23)"),
                                     ("lambda2", "mceip_lambda2", "MCEIP-lambda2 (12)-(14)")):
                ref = a["enumerate"]["problems"][prob]["solutions"]
                found = a[key]["solutions"]
                agg[prob][0] += len(ref)
                agg[prob][1] += sum(any(_match(f, r) for f in found) for r in ref)
                agg[prob][2] += sum(not any(_match(f, r) for r in ref) for f in found)
                agg[prob][3] += rec.get(stage, 0.0)
            agg["mu"][4] += rec.get("enumeration (24)-(26)", 0.0)
            system.destroy()
        for prob, (nref, nfound, nsp, tm, te) in agg.items():
            frac = nfound / nref if nref else 1.0
            print(f"{s:>3} {prob:>8} {nref:>10} {nfound:>6} {frac:>8.3f} {nsp:>8} {tm:>9.2f} {te:>9.2f}")
            total_ref += nref
            total_found += nfound
            total_spurious += nsp
    print(f"total: {total_found} of {total_ref} enumerated solutions found "
          f"({total_found / max(total_ref, 1):.4f}), {total_spurious} spurious")


if __name__ == "__main__":
    main()
