"""Benchmark: the pre-flight estimates (app/scene/limits.py) against measured runs.

Runs the paper's block study (``analyses: [mceip_mu]``, no outputs) through the CLI on crossed
P1 meshes ``nx x nx/2``, one process per size under ``/usr/bin/time -v``, and prints per size
the DOFs, the measured peak resident memory, wall and CPU time (user + system: on a shared
machine the wall time includes waiting for a core) next to the pre-flight memory and time
estimates, with their ratios, and each stage's time (results.json ``stages``). The models'
constants in app/scene/limits.py were fitted to such a table.

    .venv/bin/python benchmarks/estimates.py [--nx 56,112,224] [--ranks 1]
"""
from __future__ import annotations

import argparse
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def scene_text(nx: int) -> str:
    return (f"name: estimate-{nx}\n"
            f"system: {{type: block, nx: {nx}, ny: {nx // 2}}}\n"
            "mu: 1.1\n"
            "loading: {normal_force: 55.0, normal_steps: 10, tangential_step: 0.02, tangential_max: 10.0}\n"
            "analyses: [mceip_mu]\n")


def run(nx: int, ranks: int, folder: pathlib.Path) -> dict:
    from app.scene.limits import estimate, time_estimate
    from app.scene.schema import load_scene
    path = folder / f"s{nx}.yaml"
    path.write_text(scene_text(nx))
    scene = load_scene(path)
    est = estimate(scene)
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "app", "run", str(path), "-o", str(folder / f"out{nx}"),
           "-q", "--overwrite"]
    if ranks > 1:
        cmd = ["mpirun", "--allow-run-as-root", "-n", str(ranks), *cmd]
    t = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise SystemExit(p.stderr[-3000:])
    peaks = [int(x) * 1024 for x in re.findall(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)]
    cpu = sum(float(x) for x in re.findall(r"(?:User|System) time \(seconds\): ([\d.]+)", p.stderr))
    res = json.loads((folder / f"out{nx}" / "results.json").read_text())
    te = time_estimate(scene, est)
    return {"nx": nx, "dofs": est.dofs, "contact_nodes": est.contact_nodes, "ranks": ranks,
            "states": len(res["states"]), "classifications": res["distinct_classifications"],
            "peak_gib": round(max(peaks) / 2**30, 3), "estimate_gib": round(est.memory_bytes / 2**30, 3),
            "memory_ratio": round(est.memory_bytes / max(peaks), 2),
            "wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "time_estimate_s": round(te, 1),
            "time_ratio": round(te / wall, 2),
            "stages": {s["name"]: round(s["seconds"], 2) for s in res["stages"]}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", default="56,112,224")
    ap.add_argument("--ranks", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        for nx in [int(x) for x in args.nx.split(",")]:
            print(json.dumps(run(nx, args.ranks, pathlib.Path(d))), flush=True)


if __name__ == "__main__":
    main()
