"""The typed study result is built from the analyses' outcomes (app/io/from_outcomes.py), and it
equals what the reader of the saved file (``StudyResult.from_dict`` of results.json read back)
gives, field by field, on studies that exercise every analysis: the paper's two particles (every
analysis, enumeration included), the same on a circle (the quadratic MCEIP-mu) and the paper's
block."""
import dataclasses
import json
import math
from typing import Mapping

import numpy as np
import pytest
from mpi4py import MPI
from test_curved_particles import scene as curved_scene

from app.io.document import from_document, to_document
from app.io.result import StudyResult
from app.scene.schema import load_scene, parse_scene
from app.study.run import study

ALL = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]


def _same(a, b, where: str) -> None:
    """``a`` (built from the outcomes) and ``b`` (read from the file) hold the same data."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            if f.name in ("raw", "x"):          # raw: the same JSON data by construction; x: not in the file
                continue
            _same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, Mapping):
        assert isinstance(b, Mapping) and list(a) == list(b), where
        for k in a:
            if not str(k).startswith("_"):
                _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple, np.ndarray)):
        assert isinstance(b, (list, tuple, np.ndarray)) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, (float, np.floating)) and math.isnan(a):
        assert isinstance(b, (float, np.floating)) and math.isnan(b), where
    else:
        assert a == b and type(a == b) in (bool, np.bool_), f"{where}: {a!r} != {b!r}"


def _check(result: StudyResult) -> None:
    text = json.dumps(to_document(result.raw), allow_nan=False)
    saved = StudyResult.from_dict(from_document(json.loads(text)))
    assert len(result.states) == len(saved.states) > 0
    _same(result, saved, "study")
    # the views are not a re-parse of the dictionary: each is its own object, built from the outcomes
    assert all(type(s.mceip_mu.solutions) is tuple for s in result.states if s.mceip_mu is not None)


def test_two_particles_every_analysis():
    scene = parse_scene({"name": "two", "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30,
                                                     "signs": [1, 1]}, "mu": 2.5, "analyses": ALL})
    r = study(scene, MPI.COMM_WORLD)
    assert any(s.enumerate is not None and s.enumerate.solutions for s in r.states)
    assert any(s.mceip_mu is not None and s.mceip_mu.solutions for s in r.states)
    _check(r)


@pytest.mark.parametrize("side", ["outside", "inside"])
def test_two_particles_on_a_circle(side):
    # the quadratic MCEIP-mu of a curved obstacle (method "condensed (quadratic)")
    r = study(parse_scene(curved_scene([1, 1], 2.5, R=3.0, side=side)), MPI.COMM_WORLD)
    assert any(s.mceip_mu is not None and s.mceip_mu.raw.get("quadratic") for s in r.states)
    _check(r)


@pytest.mark.slow
def test_paper_block():
    r = study(load_scene("app/scenes/villechaise_block.yaml"), MPI.COMM_WORLD)
    assert r.final.min_mu() is not None and abs(r.final.min_mu() - 1.7) < 0.05
    _check(r)
