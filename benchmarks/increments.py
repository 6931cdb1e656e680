"""Benchmark: one quasi-static contact increment (app/loading/contact.py), today's against a baseline.

Builds the block of the default scene on a crossed P1 mesh ``nx x nx/2``, records the
increments of its tangential loading (the contact displacements of the load and the previous
state, as the block path calls the solver), then replays them with two solvers in turn,
increment by increment (A B A B ...: on a shared machine neighbouring runs compare):

- ``new``: :class:`app.loading.contact.FrictionalContact` as the app runs it (vectorised
  Jacobian, each increment started from the previous increment's slip);
- ``old``: the class as committed at ``--baseline`` (default ``main``, read from git by
  benchmarks/baseline.py), given the same inputs (it has no slip-increment start).

Prints the median time and SNES iterations per increment of each, their ratio, and the largest
difference of the reactions and displacements the two give (relative to their largest value).

    .venv/bin/python benchmarks/increments.py [--nx 224] [--steps 150] [--baseline main]
"""
from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from app.loading.contact import FrictionalContact  # noqa: E402


def record(nx: int, steps: int):
    """(Kc, mu, the recorded increments (u0, u_T_prev, g_prev)) of the block's tangential path."""
    import yaml

    from app.common.progress import Progress
    from app.common.stages import Stages
    from app.scene.schema import default_scene_path, parse_scene
    from app.systems.block.path import path
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    data["system"].update(nx=nx, ny=nx // 2)
    data["loading"]["tangential_max"] = steps * data["loading"]["tangential_step"]
    scene = parse_scene(data)
    calls = []
    solve = FrictionalContact.solve

    def spy(self, u0, u_T_prev, g_prev, d_prev=None):
        calls.append((u0.copy(), np.array(u_T_prev, copy=True), np.array(g_prev, copy=True)))
        return solve(self, u0, u_T_prev, g_prev, d_prev)

    FrictionalContact.solve = spy
    try:
        system, states, _ = path(scene, MPI.COMM_WORLD, Stages(), Progress(enabled=False))
    finally:
        FrictionalContact.solve = solve
    Kc = system.contact_schur().copy()
    system.destroy()
    tangential = calls[-(len(states) - scene.loading.normal_steps):]
    return Kc, scene.mu, tangential


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", type=int, default=224)
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--baseline", default="main")
    args = ap.parse_args()
    from benchmarks.baseline import baseline_module
    old_class = baseline_module(args.baseline, "app/loading/contact.py").FrictionalContact
    Kc, mu, calls = record(args.nx, args.steps)
    times = {"new": [], "old": []}
    its = {"new": [], "old": []}
    worst = {"r": 0.0, "u": 0.0}
    with FrictionalContact(Kc, mu) as new, old_class(Kc, mu) as old:
        d_prev = None
        for u0, uT, g in calls:
            out = {}
            for name, run in (("new", lambda: new.solve(u0, uT, g, d_prev)), ("old", lambda: old.solve(u0, uT, g))):
                t = time.perf_counter()
                out[name] = run()
                times[name].append(time.perf_counter() - t)
                its[name].append(out[name].iterations)
            d_prev = out["new"].slip_increment
            a, b = out["new"], out["old"]
            rs = max(np.max(np.abs(b.r_N)), np.max(np.abs(b.r_T)), 1e-300)
            us = max(np.max(np.abs(b.u_N)), np.max(np.abs(b.u_T)), 1e-300)
            worst["r"] = max(worst["r"], float(max(np.max(np.abs(a.r_N - b.r_N)), np.max(np.abs(a.r_T - b.r_T))) / rs))
            worst["u"] = max(worst["u"], float(max(np.max(np.abs(a.u_N - b.u_N)), np.max(np.abs(a.u_T - b.u_T))) / us))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(json.dumps({"nx": args.nx, "contact_nodes": Kc.shape[0] // 2, "increments": len(calls),
                      "median_ms": {k: round(1e3 * v, 2) for k, v in med.items()},
                      "old_over_new": round(med["old"] / med["new"], 2),
                      "total_s": {k: round(sum(v), 2) for k, v in times.items()},
                      "median_iterations": {k: statistics.median(v) for k, v in its.items()},
                      "total_iterations": {k: int(sum(v)) for k, v in its.items()},
                      "max_rel_diff": worst}), flush=True)


if __name__ == "__main__":
    main()
