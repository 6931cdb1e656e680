"""MCEIP-lambda^2 searched on the exact slip-node reduction where its proof fails
(app/analyses/mceip_lambda2/reduced_search.py), as it is above ``mcp.lambda2_full_search_max_dofs``:
the solutions it finds are those of the SNES VI search on the full system (an independent
computation: another formulation, another solver), state by state, along paths held at a friction
coefficient above the MCEIP-mu onset (a divergence rate exists)."""
import copy

import numpy as np
import pytest
from conftest import run_scene

BLOCK = {"name": "rs", "system": {"type": "block", "length": 80.0, "height": 40.0, "thickness": 9.6, "nx": 20,
                                  "ny": 10, "pattern": "crossed", "E": 5.0, "nu": 0.48, "density": 1.2e-9},
         "mu": 1.1, "loading": {"normal_force": 55.0, "normal_steps": 10, "tangential_step": 0.02,
                                "tangential_max": 10.0},
         "analyses": ["mceip_mu", "mceip_lambda2"]}


def _lambda2(res: dict) -> list[dict]:
    return [s["analyses"]["mceip_lambda2"] for s in res["states"]
            if isinstance((s.get("analyses") or {}).get("mceip_lambda2"), dict)]


@pytest.mark.parametrize("nx, mu", [(20, 2.0), (10, 2.5), (10, 3.0)])
def test_the_search_on_the_reduction_finds_the_full_systems_solutions(nx, mu):
    data = copy.deepcopy(BLOCK)
    data["system"].update(nx=nx, ny=nx // 2)
    data["mceip_lambda2_mu"] = mu
    full = _lambda2(run_scene(data))
    data["settings"] = {"mcp": {"lambda2_full_search_max_dofs": 0}}
    reduced = _lambda2(run_scene(data))
    assert len(full) == len(reduced)
    searched = 0
    for f, r in zip(full, reduced):
        if f["certified"]:                      # proven on the reduction: the same answer
            assert r["result"] == f["result"] and r["certified"]
            continue
        searched += 1
        assert not r["certified"]
        assert "searched_on_reduction" in r["search"], r["search"].get("note")
        ff = [s for s in f["solutions"] if not s["ill_conditioned"]]
        rr = r["solutions"]
        assert len(rr) == len(ff), (f["result"], r["result"])
        for a, b in zip(sorted(ff, key=lambda s: s["value"]), rr):
            assert abs(a["value"] - b["value"]) <= 1e-9 * a["value"]
            assert a["pattern"] == b["pattern"]
            assert np.allclose(a["x_Ts"], b["x_Ts"], atol=1e-8)
        # none outside the intervals it searched, which the proof set aside
        gaps = r["certificate"]["detail"]["proven_empty_except"]
        assert all(any(lo <= s["value"] <= hi for lo, hi in gaps) for s in rr)
    assert searched > 0
