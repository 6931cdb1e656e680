"""Time of the embedded default study (the paper's block), serial, once forms are compiled.

Runs the study twice in one process (the first run compiles the DOLFINx forms and fills the
mesh cache) and prints the second run's total and per-stage wall times, with the machine.

    .venv/bin/python benchmarks/study_time.py [SCENE.yaml]
"""
from __future__ import annotations

import platform
import sys
import time

from mpi4py import MPI
from petsc4py import PETSc

from app.scene.schema import default_scene_path, load_scene
from app.study.run import study


def main() -> None:
    scene = load_scene(sys.argv[1] if len(sys.argv) > 1 else default_scene_path())
    import dolfinx
    print(f"machine: {platform.machine()}, {platform.node()}, python {platform.python_version()}, "
          f"DOLFINx {dolfinx.__version__}, PETSc {'.'.join(map(str, PETSc.Sys.getVersion()))}, "
          f"{MPI.COMM_WORLD.size} rank(s)")
    t0 = time.perf_counter()
    study(scene, MPI.COMM_WORLD)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = study(scene, MPI.COMM_WORLD).to_dict()
    second = time.perf_counter() - t0
    print(f"scene '{scene.name}': {len(res['states'])} states, {res['distinct_classifications']} distinct classifications")
    print(f"first run (compiles forms): {first:.2f} s; second run: {second:.2f} s (issue 14 target: at most 1.5 s, outputs off, forms compiled)")
    for st in res["stages"]:
        print(f"  {st['name']:<36} {st['seconds']:8.3f} s  x{st['count']}")


if __name__ == "__main__":
    main()
