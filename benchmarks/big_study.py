"""The 100k-DOF study of issue 14 in its own process (serial or under mpirun).

The paper's scene on a crossed P1 mesh ``nx x nx/2`` (224 x 112: 101,026 DOFs), MCEIP-mu at every
distinct classification along the path, then the sufficient condition (17)-(18) at the final
state. Prints one JSON line per analysed classification (so a run stopped by a time limit still
reports how far it got) and a final JSON line with the wall time and the stage times (rank 0).

    .venv/bin/python benchmarks/big_study.py [--nx 224]
    mpirun -n 2 .venv/bin/python benchmarks/big_study.py
"""
from __future__ import annotations

import argparse
import json
import time

from mpi4py import MPI


def _dofs(description) -> int | None:
    """The DOF count in the system's description ("..., 101026 DOFs")."""
    import re
    m = re.search(r"(\d+) DOFs", str(description))
    return int(m.group(1)) if m else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", type=int, default=224)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    import yaml

    import app.analyses.runner as runner
    import app.study.run as study
    import app.study.scheduler as distributed
    from app.scene.schema import default_scene_path, parse_scene
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    data.update(name="bench-100k", analyses=["mceip_mu"])
    data["system"].update(nx=args.nx, ny=args.nx // 2)
    scene = parse_scene(data)
    small = parse_scene({**data, "system": {**data["system"], "nx": 4, "ny": 2},
                         "loading": {**data["loading"], "tangential_max": data["loading"]["tangential_step"]}})
    study.study(small, comm)          # JIT-compile the forms first: the timed run is the study alone

    t0 = time.perf_counter()
    count = [0]
    analyse = runner.analyse_state
    mceip_mu = runner.state_mceip_mu

    def counted(system, p, sc, s, **kw):
        """MCEIP-mu of one classification (rank 0's share under MPI), with a progress line."""
        out = mceip_mu(system, p, sc, s, **kw)          # a typed outcome (app.analyses.outcomes)
        count[0] += 1
        if comm.rank == 0:
            cert = getattr(out, "certificate", None)
            sols = getattr(out, "solutions", None) or []
            print(json.dumps({"classification": count[0], "slip": s, "t": round(time.perf_counter() - t0, 3),
                              "search_s": (getattr(out, "search", None) or {}).get("seconds"),
                              "certificate_s": None if cert is None else cert.seconds,
                              "status": None if cert is None else cert.status,
                              "found": len(sols), "values": [round(float(x.value), 6) for x in sols][:4]}),
                  flush=True)
        return out

    runner.state_mceip_mu = counted       # analyse_state (s = 0) and analyse_condensed_distributed call it
    distributed.state_mceip_mu = counted

    def final_sufficient(system, states, cache):
        """The sufficient condition at the final state (its classification's pencils)."""
        from app.loading.classify import classify
        t = time.perf_counter()
        cls = classify(states[-1], scene.mu, scene.settings.classify_rtol)
        out = analyse(system, cls, scene.model_copy(update={"analyses": ["sufficient"]}))
        suff = out.get("sufficient")
        return {"sufficient": None if suff is None else {"satisfied": bool(suff.satisfied),
                                                         "lambda2": [float(v) for v in suff.lambda2]},
                "seconds": time.perf_counter() - t}

    res = study.study(scene, comm, inspect=final_sufficient).to_dict()
    wall = time.perf_counter() - t0
    if comm.rank == 0:
        suff = res["inspection"]["sufficient"] or {}
        print(json.dumps({"done": True, "wall_s": wall, "dofs": _dofs(res["system"]),
                          "states": len(res["states"]), "classifications": res["distinct_classifications"],
                          "stages": res["stages"], "ranks": comm.size,
                          "final_sufficient": {"satisfied": suff.get("satisfied"), "lambda2": suff.get("lambda2"),
                                               "seconds": res["inspection"]["seconds"]},
                          "final_mu": [x["value"] for x in res["states"][-1]["analyses"]["mceip_mu"].get("solutions", [])]}),
              flush=True)


if __name__ == "__main__":
    main()
