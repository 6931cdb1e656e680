"""The typed study result (app/io/result.py) is the one carrier of a study's results: results.json
is written from it, and reading the file back gives the same result, every field and every key
(also the keys an analysis adds beyond the described ones), on studies that exercise every
analysis: the paper's two particles (every analysis, enumeration included), the same on a circle
(the quadratic MCEIP-mu) and the paper's block. What a run keeps in memory only (mode vectors,
proof pencils) is on the run's result and never in the file. No module of app/ reads a
dictionary twin of the result."""
import json
import math
import pathlib
import re

import numpy as np
import pytest
from mpi4py import MPI
from test_curved_particles import scene as curved_scene

from app.io.document import from_document
from app.io.result import StudyResult
from app.scene.schema import load_scene, parse_scene
from app.study.run import study

ROOT = pathlib.Path(__file__).resolve().parents[1]
ALL = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]


def _same(a, b, where: str) -> None:
    """``a`` and ``b`` hold the same data (NaN equal to NaN, arrays element by element)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {sorted(set(a) ^ set(b))}"
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple, np.ndarray)):
        assert isinstance(b, (list, tuple, np.ndarray)) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _check(result: StudyResult) -> StudyResult:
    doc = result.to_json()
    text = json.dumps(doc, allow_nan=False)
    assert json.loads(text) == doc                           # JSON data as it is
    saved = StudyResult.from_dict(from_document(json.loads(text)))
    assert len(result.states) == len(saved.states) > 0
    _same(result.to_dict(), saved.to_dict(), "study")
    assert saved.to_json() == doc
    return saved


def _in_memory(result: StudyResult) -> tuple[int, int]:
    """Mode vectors and proofs the run kept (none of them is in the file)."""
    vectors = proofs = 0
    for st in result.states:
        a = st.analyses
        for m in (a.mceip_mu, a.mceip_lambda2, a.sufficient):
            if m is None:
                continue
            vectors += sum(s.x is not None for s in (m.modes if m is a.sufficient else m.solutions))
        proofs += a.mceip_mu is not None and a.mceip_mu.proof is not None
    return vectors, proofs


def test_two_particles_every_analysis():
    scene = parse_scene({"name": "two", "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30,
                                                     "signs": [1, 1]}, "mu": 2.5, "analyses": ALL})
    r = study(scene, MPI.COMM_WORLD)
    assert any(s.enumerate is not None and s.enumerate.solutions for s in r.states)
    assert any(s.mceip_mu is not None and s.mceip_mu.solutions for s in r.states)
    saved = _check(r)
    assert _in_memory(r)[1] > 0 and _in_memory(saved) == (0, 0)
    assert type(r.final.min_mu()).__name__ == "CriticalMu" and type(saved.final.min_mu()).__name__ == "CriticalMu"


@pytest.mark.parametrize("side", ["outside", "inside"])
def test_two_particles_on_a_circle(side):
    # the quadratic MCEIP-mu of a curved obstacle (method "condensed (quadratic)"): a key beyond the described ones
    r = study(parse_scene(curved_scene([1, 1], 2.5, R=3.0, side=side)), MPI.COMM_WORLD)
    assert any(s.mceip_mu is not None and (s.mceip_mu.model_extra or {}).get("quadratic") for s in r.states)
    _check(r)


@pytest.mark.slow
def test_paper_block():
    r = study(load_scene("app/scenes/villechaise_block.yaml"), MPI.COMM_WORLD)
    assert r.final.min_mu() is not None and abs(r.final.min_mu() - 1.7) < 0.05
    _check(r)


def test_no_dictionary_twin_of_the_result_in_the_app():
    """The result has no ``raw`` dictionary and no private ``_proof``/``_x`` keys: what is kept in
    memory is a typed field (``MceipMuResult.proof``, ``MceipSolution.x``)."""
    found = []
    pattern = re.compile(r"\.raw\b|\[\"_proof\"\]|\[\"_x\"\]|\"_proof\"|\"_x\"")
    for path in sorted((ROOT / "app").rglob("*.py")):
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if pattern.search(line):
                found.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not found, "\n".join(found)
