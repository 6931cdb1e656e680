"""Solver-tolerance study: the refinement quantities and the time against the solver tolerances.

One refinement level (the paper's block, crossed P1, plane stress; nx = 20 and 40 by default) is
run with the default settings and then with one setting changed at a time:

  settings.mcp.rtol          SNES VI relative tolerance of the MCEIP-mu MCP runs   (default 1e-12)
  settings.mcp.accept_tol    acceptance of an MCP candidate as a solution          (default 1e-8)
  settings.eig.tol           SLEPc Krylov-Schur tolerance (sufficient condition)   (default 1e-10)
  settings.classify_rtol     classification of the contact nodes                   (default 1e-8)
  settings.mcp.pattern_starts / shift_rounds   the search effort                   (default true / 6)

For each it prints the relative change of every quantity from the default run and the wall time.
The contact increments' SNES tolerance is fixed in app/loading/contact.py (residual 1e-14 of the
reaction scale, every increment then checked against Signorini-Coulomb to 1e-9), so it is not
varied here.

    .venv/bin/python benchmarks/tolerance_study.py [--nx 20 40]
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpi4py import MPI  # noqa: E402

QOIS = ("final_mu", "first_mu_ux", "first_mu", "lambda2", "depth", "tangential_resultant", "sliding_ux")
VARIANTS = [
    ("mcp.rtol", [1e-4, 1e-6, 1e-8, 1e-10]),
    ("mcp.accept_tol", [1e-4, 1e-6, 1e-10]),
    ("eig.tol", [1e-3, 1e-5, 1e-8]),
    ("classify_rtol", [1e-3, 1e-5, 1e-6, 1e-10, 1e-12]),
    ("mcp.pattern_starts", [False]),
    ("mcp.shift_rounds", [0]),
]


def _scene(base, key: str | None, value):
    if key is None:
        return base
    s = base.settings
    if key.startswith("mcp."):
        s = s.model_copy(update={"mcp": s.mcp.model_copy(update={key[4:]: value})})
    elif key.startswith("eig."):
        s = s.model_copy(update={"eig": s.eig.model_copy(update={key[4:]: value})})
    else:
        s = s.model_copy(update={key: value})
    return base.model_copy(update={"settings": s})


def _rel(a, b) -> str:
    if a is None or b is None:
        return "same" if a is b else "CHANGED"
    d = abs(a - b) / max(abs(b), 1e-300)
    return "0" if d == 0 else f"{d:.1e}"


def run(nx_values=(20, 40), say=print) -> list[dict]:
    import yaml

    from app.scene.schema import default_scene_path, parse_scene
    from app.study.refinement import run_level
    data = yaml.safe_load(default_scene_path().read_text())
    data.update(name="tolerances", analyses=[], mceip_lambda2_mu=2.0, refinement={"levels": [10, 20]})
    base = parse_scene(data)
    run_level(base.model_copy(update={"loading": base.loading.model_copy(update={"tangential_max": 0.02})}),
              4, 1, "stress", MPI.COMM_WORLD)                       # compile the forms
    rows = []
    for nx in nx_values:
        say(f"\n== solver tolerances: paper block, crossed P1 plane stress nx = {nx} (relative change of each "
            f"quantity from the default settings; time of the level) ==")
        say(f"{'setting':>20} {'value':>8} " + " ".join(f"{q:>12}" for q in QOIS) + f" {'wall[s]':>8}")
        ref = None
        for key, values in [(None, [None])] + VARIANTS:
            for v in values:
                t0 = time.perf_counter()
                row, _ = run_level(_scene(base, key, v), nx, 1, "stress", MPI.COMM_WORLD)
                wall = time.perf_counter() - t0
                if ref is None:
                    ref = row
                    say(f"{'default':>20} {'':>8} " + " ".join(
                        f"{(row[q] if row[q] is not None else float('nan')):>12.6g}" for q in QOIS) + f" {wall:>8.2f}")
                else:
                    say(f"{key:>20} {str(v):>8} " + " ".join(f"{_rel(row[q], ref[q]):>12}" for q in QOIS)
                        + f" {wall:>8.2f}")
                rows.append({"nx": nx, "setting": key or "default", "value": v, "wall_s": wall,
                             **{q: row[q] for q in QOIS}})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nx", type=int, nargs="+", default=[20, 40])
    run(ap.parse_args().nx)


if __name__ == "__main__":
    main()
