"""Invariance: the same study in mm/N/MPa and in m/N/Pa, and with E scaled by 1e6, gives the same
classifications and mu values (1e-8 relative) and lambda^2 scaled exactly."""
import pytest
from conftest import run_scene

MM = {"name": "inv", "mu": 1.1, "mceip_lambda2_mu": 2.0,
      "system": {"type": "block", "nx": 10, "ny": 5, "length": 80.0, "height": 40.0, "thickness": 9.6,
                 "E": 5.0, "nu": 0.48, "density": 1.2e-9},
      "loading": {"normal_force": 55.0, "normal_steps": 10, "tangential_step": 0.02, "tangential_max": 10.0},
      "analyses": ["necessary", "sufficient", "mceip_mu", "mceip_lambda2"]}


def _si():
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in MM.items()}
    d["units"] = "m-N-Pa-kg-s"
    for key in ("length", "height", "thickness"):
        d["system"][key] = MM["system"][key] * 1e-3
    d["system"]["E"] = MM["system"]["E"] * 1e6            # MPa -> Pa
    d["system"]["density"] = MM["system"]["density"] * 1e12  # tonne/mm^3 -> kg/m^3
    for key in ("tangential_step", "tangential_max"):
        d["loading"][key] = MM["loading"][key] * 1e-3
    return d


def _stiff():
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in MM.items()}
    d["system"]["E"] = MM["system"]["E"] * 1e6
    for key in ("tangential_step", "tangential_max"):    # the same forces need 1e-6 the displacements
        d["loading"][key] = MM["loading"][key] * 1e-6
    return d


@pytest.fixture(scope="module")
def reference():
    return run_scene(MM)


def _compare(a, b, lambda2_factor):
    assert len(a["states"]) == len(b["states"])
    n_mu = n_l2 = 0
    for sa, sb in zip(a["states"], b["states"]):
        assert [n["status"] for n in sa["nodes"]] == [n["status"] for n in sb["nodes"]]
        assert [n["sign"] for n in sa["nodes"]] == [n["sign"] for n in sb["nodes"]]
        assert sb["load"]["normal_resultant"] == pytest.approx(sa["load"]["normal_resultant"], rel=1e-8)
        A, B = sa["analyses"], sb["analyses"]
        for key, factor in (("mceip_mu", 1.0), ("mceip_lambda2", lambda2_factor)):
            va = sorted((x["value"], x["pattern"]) for x in A[key]["solutions"])
            vb = sorted((x["value"], x["pattern"]) for x in B[key]["solutions"])
            assert [p for _, p in va] == [p for _, p in vb]
            assert [v * factor for v, _ in va] == pytest.approx([v for v, _ in vb], rel=1e-8)
            n_mu += key == "mceip_mu" and len(va)
            n_l2 += key == "mceip_lambda2" and len(va)
        assert A["necessary"]["satisfied"] == B["necessary"]["satisfied"]
        assert [v * lambda2_factor for v in A["sufficient"]["lambda2"]] == pytest.approx(B["sufficient"]["lambda2"], rel=1e-8)
    assert n_mu > 0 and n_l2 > 0  # the comparison is not vacuous


@pytest.mark.slow
def test_si_units_give_the_same_results(reference):
    res = _si_res = run_scene(_si())
    assert res["units"]["length"] == "m" and reference["units"]["length"] == "mm"
    _compare(reference, res, 1.0)      # lambda^2 is in 1/s^2 in both unit systems


@pytest.mark.slow
def test_E_scaled_by_1e6(reference):
    _compare(reference, run_scene(_stiff()), 1e6)   # lambda^2 = stiffness / mass scales with E
