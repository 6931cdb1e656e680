"""A regression guard: the default (paper) study gives the answers of a stored earlier run.

``tests/data/default_study_answers.json`` is a snapshot of the app's own output, written by
``answers()`` below from a run of the code path before the speed work of issue 14 (commit
ab195b8): every classification, node status and sign, and for each distinct classification the
necessary-condition eigenvalues, the sufficient-condition eigenvalues, and every MCEIP-mu and
MCEIP-lambda^2 value, mode x_Ts and pattern. Values must agree to 1e-8 (relative, absolute
below 1), patterns and classifications exactly. It proves nothing about correctness: it says
that an answer changed, not which one is right.

The correctness of these answers is checked against an independent numpy computation in
tests/test_default_independent.py (equilibrium, classification, (19), (17)-(18), every critical
mu of MCEIP-mu, the paper's numbers). What only this snapshot guards: MCEIP-lambda^2 (12)-(14)
at the classifications where the necessary condition (19) holds and the mode would leave some
slip nodes stuck (the app proves "no solution" there; no independent computation here), the
MCEIP-mu lists of the three states with 16 and 17 slip nodes beyond the solutions' own supports
(not enumerated by default there), and the reproducibility of the whole answer set to 1e-8 across
code changes (``benchmarks/run_all.py`` reuses ``answers`` and ``_compare``). Not timed: the
speed targets live in benchmarks/ (``make bench``).
"""
import json
import pathlib

import pytest
import yaml
from conftest import run_scene

from app.scene.schema import default_scene_path

REFERENCE = pathlib.Path(__file__).parent / "data" / "default_study_answers.json"


def answers(states: list[dict]) -> dict:
    """The answers of a study, in a compact form (the reference file's format)."""
    out = {"states": [], "analyses": {}}
    for s in states:
        out["states"].append({"index": s["index"], "classification": s["classification"],
                              "status": "".join(n["status"][1] for n in s["nodes"]),   # t(ick), l(ip), r(ee), e(ro)
                              "signs": [n["sign"] for n in s["nodes"]],
                              "shared_with": s["analyses_shared_with"]})
        if s["analyses_shared_with"] is not None:
            continue
        a = s["analyses"]
        d = {}
        if "necessary" in a and not a["necessary"].get("failed"):
            d["necessary"] = {k: a["necessary"][k] for k in ("satisfied", "min_eig_K_sym", "min_eig_M_sym")}
        if "sufficient" in a and not a["sufficient"].get("failed"):
            d["sufficient"] = {"satisfied": a["sufficient"]["satisfied"], "lambda2": a["sufficient"]["lambda2"]}
        for name in ("mceip_mu", "mceip_lambda2"):
            if name in a and not a[name].get("failed"):
                d[name] = [{"value": x["value"], "x_Ts": x["x_Ts"], "pattern": x["pattern"]}
                           for x in a[name]["solutions"]]
        out["analyses"][str(s["index"])] = d
    return out


def _compare(ref, got, path, bad):
    if isinstance(ref, dict):
        assert isinstance(got, dict), path
        if set(ref) != set(got):
            bad.append(f"{path}: keys {sorted(ref)} != {sorted(got)}")
        for k in set(ref) & set(got):
            _compare(ref[k], got[k], f"{path}/{k}", bad)
    elif isinstance(ref, list):
        if not isinstance(got, list) or len(ref) != len(got):
            bad.append(f"{path}: {ref!r} != {got!r}")
            return
        for i, (r, g) in enumerate(zip(ref, got)):
            _compare(r, g, f"{path}[{i}]", bad)
    elif isinstance(ref, float) and not isinstance(ref, bool):
        if not abs(ref - got) <= 1e-8 * max(1.0, abs(ref), abs(got)):
            bad.append(f"{path}: {ref!r} != {got!r}")
    elif ref != got:
        bad.append(f"{path}: {ref!r} != {got!r}")


@pytest.mark.skipif(not REFERENCE.exists(), reason="reference answers missing")
def test_default_study_answers_unchanged():
    scene = yaml.safe_load(default_scene_path().read_text())
    scene.pop("outputs", None)
    got = answers(run_scene(scene)["states"])
    ref = json.loads(REFERENCE.read_text())
    bad: list[str] = []
    _compare(ref, got, "", bad)
    assert not bad, f"{len(bad)} differences, first: {bad[:5]}"
    # and the paper's figures are among them (the paper's section 5)
    final = ref["analyses"][str(max(int(k) for k in ref["analyses"]))]
    assert final["mceip_mu"][0]["value"] == pytest.approx(1.7048, abs=1e-4)
