"""A regression guard: the default (paper) study gives the answers of a stored earlier run.

``tests/data/default_study_answers.json`` holds the answers of the app's own output in the
compact form of ``benchmarks/compare_results.py`` (:func:`answers`: every classification, node
status and sign, and for each distinct classification the necessary-condition eigenvalues, the
sufficient-condition eigenvalues, every MCEIP-mu and MCEIP-lambda^2 value, mode x_Ts and pattern,
and the certificate statuses), compared by that script's :func:`compare`. The values were first
written from the code path before the speed work of issue 14 (commit ab195b8); the file was
rewritten with the certificate statuses on 2026-12-04 (``compare_results.py --write-answers``)
from a run that the old file's comparison passed, so its values are still those of ab195b8. Values must agree to 1e-8 (relative, absolute
below 1), patterns, classifications and statuses exactly. It proves nothing about correctness: it
says that an answer changed, not which one is right. tests/test_gmsh_examples.py guards a shipped
example (the L-shaped body) the same way.

The correctness of these answers is checked against an independent numpy computation in
tests/test_default_independent.py (equilibrium, classification, (19), (17)-(18), every critical
mu of MCEIP-mu, the paper's numbers). What only this snapshot guards: MCEIP-lambda^2 (12)-(14)
at the classifications where the necessary condition (19) holds and the mode would leave some
slip nodes stuck (the app proves "no solution" there; no independent computation here), the
MCEIP-mu lists of the three states with 16 and 17 slip nodes beyond the solutions' own supports
(not enumerated by default there), and the reproducibility of the whole answer set to 1e-8 across
code changes (``benchmarks/run_all.py`` reuses this comparison). Not timed: the speed targets live
in benchmarks/ (``make bench``).
"""
import json
import pathlib
import sys

import pytest
import yaml
from conftest import ROOT, run_scene

from app.scene.schema import default_scene_path

sys.path.insert(0, str(ROOT / "benchmarks"))
from compare_results import answers, compare  # noqa: E402  (the comparison script itself)

REFERENCE = pathlib.Path(__file__).parent / "data" / "default_study_answers.json"


def differences(reference: dict, results: dict) -> list[str]:
    """The differences of ``results``' answers from the stored ``reference`` answers (rtol 1e-8)."""
    return [f"{key}: {where[:3]}" for key, where in compare(reference, answers(results), 1e-8).items()]


@pytest.mark.skipif(not REFERENCE.exists(), reason="reference answers missing")
def test_default_study_answers_unchanged():
    scene = yaml.safe_load(default_scene_path().read_text())
    scene.pop("outputs", None)
    ref = json.loads(REFERENCE.read_text())
    bad = differences(ref, run_scene(scene))
    assert not bad, f"{len(bad)} kinds of differences, first: {bad[:5]}"
    # and the paper's figures are among them (the paper's section 5)
    final = ref["analyses"][str(max(int(k) for k in ref["analyses"]))]
    assert final["mceip_mu"]["solutions"][0]["value"] == pytest.approx(1.7048, abs=1e-4)
    assert final["mceip_mu"]["certified"] and final["mceip_mu"]["onset_proven"]
