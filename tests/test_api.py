"""The public API (app/api.py, app/io/result.py, app/io/document.py) and the stability of results.json.

results.json must keep its content: only ``format_version`` is new in format 1, and format 2
writes non-finite numbers as ``null`` listed in a ``non_finite`` block (read back by
``from_document``, which also reads format 1). Two checks:

* the two-particle scene of the README: the CLI's results.json equals, key by key and value by
  value, the one written by the code before the API existed (main at ab195b8, kept in
  tests/data/results_two_particles_v0.json without its timings);
* the paper's block (the shipped default scene): the CLI's results.json has exactly the key
  paths of the one written before the API (tests/data/results_keys_villechaise_block.txt, made
  with scripts/results_keys.py), and the API's ``to_json()`` equals the CLI's results.json
  except for timings and the record of the files the CLI drew.

Keys that later analyses add to format 1 are listed in ``ADDED_KEYS``: adding an optional key is
compatible, removing or changing one is not (then raise FORMAT_VERSION in app/io/document.py).
"""
from __future__ import annotations

import json
import math
import pathlib

import pytest
import yaml
from conftest import ROOT, minimal_study, run_cli, run_cli_here

import app
from app.io.document import FORMAT_VERSION, from_document, to_document
from app.io.result import CriticalMu, StudyResult

DATA = pathlib.Path(__file__).parent / "data"
#: keys that vary from run to run (wall times) or describe what the CLI drew, not what it computed
VOLATILE = {"stages", "wall_seconds", "analysis_seconds", "seconds", "versions"}
#: solver evidence: how an answer was obtained (which search, its runs, iterations, its summary
#: line). It documents the solver, not the answer, and changes when a solver improves (issue 11's
#: certified dense search replaced the SNES VI search of the condensed MCEIP-mu): its keys and
#: values are not compared, while every answer (values, modes, patterns, classifications,
#: reactions, eigenvalues) must stay the same.
EVIDENCE = {"search", "result", "found_by", "found_count", "iterations", "residual", "complementarity",
            "min_x_Ts", "min_y_Ts",
            # the sufficient condition's eigensolver record: none runs where MCEIP-lambda^2 decides it
            "eigensolver", "converged", "real_candidates"}
#: keys added to format 1 since v0 (a reader of format 1 ignores keys it does not know)
ADDED_KEYS = {"format_version", "certified", "certificate", "ill_conditioned", "margin_y_stick",
              "pattern_verified", "pattern_residual", "newton_residual", "complementarity", "min_x_Ts",
              "min_y_Ts",
              "limits", "max_states", "max_dofs", "max_contact_nodes", "max_memory_gb",   # scene_config.settings.limits
              # the proven MCEIP-mu (issue 18): the two claims, proven enclosures and margins, new settings
              "onset", "complete", "enclosure", "proven_min_x_Ts", "proven_margin_y_stick", "certify_all_max",
              "certify_all_seconds",
              "time"}   # units.time: the two particles' units are the scene's (app/systems/units.py)

TWO_PARTICLES = """\
name: two-particles
system: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}
mu: 2.5
analyses: [necessary, sufficient, mceip_lambda2, mceip_mu, enumerate]
"""


def _differences(old, new, path: str = "", skip=frozenset()) -> list[str]:
    """Where two JSON documents differ (floats to 1e-9 relative: other BLAS builds)."""
    out: list[str] = []
    if isinstance(old, dict) and isinstance(new, dict):
        for k in sorted(set(old) | set(new)):
            if k in skip or ("seconds" in skip and k.endswith("_seconds")):   # every timing is volatile
                continue
            if k not in new:
                out.append(f"{path}.{k}: missing in the new results")
            elif k not in old:
                if k not in ADDED_KEYS:
                    out.append(f"{path}.{k}: new key (not in ADDED_KEYS)")
            else:
                out += _differences(old[k], new[k], f"{path}.{k}", skip)
    elif isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path}: {len(old)} items before, {len(new)} now"]
        for i, (a, b) in enumerate(zip(old, new)):
            out += _differences(a, b, f"{path}[{i}]", skip)
    elif isinstance(old, float) and isinstance(new, (int, float)) and not isinstance(new, bool):
        if not math.isclose(old, new, rel_tol=1e-9, abs_tol=1e-12 * max(1.0, abs(old))):
            out.append(f"{path}: {old!r} before, {new!r} now")
    elif old != new:
        out.append(f"{path}: {old!r} before, {new!r} now")
    return out


def test_two_particles_results_json_unchanged(scene_file, tmp_path):
    scene = scene_file(TWO_PARTICLES)
    proc = run_cli_here("run", str(scene), "-o", str(tmp_path / "out"), "-q")
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "out" / "results.json").read_text()
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"results.json holds {c}"))
    assert doc["format_version"] == FORMAT_VERSION == 3 and '"inf"' not in text
    assert doc["non_finite"]["values"] and "JSON has no infinity" in doc["non_finite"]["reason"]
    new = from_document(doc)
    old = from_document(json.loads((DATA / "results_two_particles_v0.json").read_text()))
    # scene_config echoes the validated scene with every default: it grows with the schema
    # (docs/scene-keys.md); the scene itself is compared through the analyses it produced.
    diffs = _differences(old, new, skip=VOLATILE | EVIDENCE | {"scene_config"})
    assert not diffs, "\n".join(diffs[:20])
    assert set(old["scene_config"]) <= set(new["scene_config"])
    # the differences function does see a change of an answer
    changed = json.loads(json.dumps(new))
    changed["states"][0]["analyses"]["mceip_mu"]["solutions"][0]["value"] *= 1 + 1e-6
    assert _differences(old, changed, skip=VOLATILE | EVIDENCE | {"scene_config"})
    changed = json.loads(json.dumps(new))
    changed["states"][0]["analyses"]["mceip_mu"]["solutions"][0]["pattern"][0] = "stick"
    assert _differences(old, changed, skip=VOLATILE | EVIDENCE | {"scene_config"})


def test_two_particles_api_typed_fields():
    """S1 = +1, S2 = -1 (Table 1's case with several modes): MCEIP-mu has slip-stick, stick-slip
    and slip-slip solutions, all three proven by the enumeration; the typed fields hold what
    results.json holds."""
    r = app.run_study(app.load_scene(yaml.safe_load(TWO_PARTICLES)))
    st = r.final
    assert len(r) == 1 and st.index == 0 and r.state(0) is st and r.first_instability() is st
    mu = st.mceip_mu
    assert [s.pattern for s in mu.solutions] == [("slip", "stick"), ("stick", "slip"), ("slip", "slip")]
    assert st.enumerate.search == {} and st.enumerate.complete is True
    assert len(st.enumerate.values) == 3 and max(abs(st.enumerate.values - mu.values)) < 1e-9 * mu.max()
    assert str(st.min_mu()) == f"{mu.values[0]:.4f}" and st.min_mu() == mu.values[0]
    written = r.to_json()["states"][0]["analyses"]["mceip_mu"]["solutions"]       # as in results.json
    for sol, d in zip(mu.solutions, written):
        assert sol.value == d["value"] and sol.x_Ts.dtype == float and list(sol.x_Ts) == d["x_Ts"]
        assert abs(sol.x_Ts.sum() - 1) < 1e-9 and not sol.x_Ts.flags.writeable
        assert sol.pattern == tuple(d["pattern"]) and sol.evidence["residual"] == d["residual"]
        assert sol.certified is d["certified"] is True     # below the cap: proven (app/analyses/mceip_mu/state.py)
    assert st.mceip_mu.certified is True and st.mceip_mu.certificate.status == "proven"
    assert st.mceip_lambda2.mu == 2.5 and st.mceip_lambda2.min() is None
    assert st.sufficient.satisfied is False and st.max_lambda2() is None and st.necessary.satisfied
    with pytest.raises(KeyError):
        r.state(5)


def test_critical_mu_prints_four_decimals_and_keeps_the_value():
    m = CriticalMu(1.7048043295803184)
    assert str(m) == "1.7048" and f"{m}" == "1.7048" and f"{m:.10g}" == "1.70480433"
    assert float(m) == 1.7048043295803184 and repr(m) == "1.7048043295803184"
    assert json.dumps({"mu": m}) == '{"mu": 1.7048043295803184}'
    assert str(CriticalMu(60.80579)) == "60.8058"


def test_solution_carries_keys_added_by_other_analyses():
    d = {"value": 2.0, "x_Ts": [0.25, 0.75], "pattern": ["slip", "slip"], "residual": 1e-15,
         "certified": True, "certificate": {"status": "proven", "method": "branch-and-bound", "interval": [0, 10]},
         "new": 1}
    r = minimal_study([{"index": 0, "classification": {"slip": 2}, "analyses": {"mceip_mu": {"solutions": [d]}}}])
    sol = r.final.mceip_mu.solutions[0]
    assert sol.certified is True and sol.certificate.method == "branch-and-bound" and sol.all_slip
    assert sol.model_extra == {"new": 1} and sol.certificate.interval == [0, 10]
    assert r.to_json()["states"][0]["analyses"]["mceip_mu"]["solutions"][0] == d
    assert r.to_json()["format_version"] == FORMAT_VERSION
    assert StudyResult.from_json(r.to_json()).to_json() == r.to_json()


def test_non_finite_numbers_are_null_with_a_reason():
    """Format 2: every non-finite number is null, listed by its JSON pointer with its value;
    from_document restores it, reads format 1's "inf" strings, and refuses what it cannot read."""
    import numpy as np
    results = {"scene": "s", "states": [{"index": 0, "analyses": {"x": {"interval": [0.0, math.inf],
                                                                         "low": -math.inf, "odd": np.float64("nan"),
                                                                         "a/b~c": [1.5, math.inf]}}}]}
    doc = to_document(results)
    json.dumps(doc, allow_nan=False)                        # valid JSON: no Infinity, no NaN
    x = doc["states"][0]["analyses"]["x"]
    assert x["interval"] == [0.0, None] and x["low"] is None and x["odd"] is None and x["a/b~c"] == [1.5, None]
    assert doc["non_finite"]["values"] == {"/states/0/analyses/x/interval/1": "+inf", "/states/0/analyses/x/low": "-inf",
                                           "/states/0/analyses/x/odd": "nan", "/states/0/analyses/x/a~1b~0c/1": "+inf"}
    back = from_document(json.loads(json.dumps(doc)))["states"][0]["analyses"]["x"]
    assert back["interval"] == [0.0, math.inf] and back["low"] == -math.inf and math.isnan(back["odd"])
    assert back["a/b~c"] == [1.5, math.inf] and "non_finite" not in from_document(doc)
    v1 = {"format_version": 1, "states": [{"interval": [0.0, "inf"], "low": "-inf", "name": "infinite"}]}
    assert from_document(v1)["states"][0] == {"interval": [0.0, math.inf], "low": -math.inf, "name": "infinite"}
    with pytest.raises(ValueError, match="format_version = 4"):
        from_document({"format_version": 4})
    with pytest.raises(ValueError, match="names no null number"):
        from_document({"format_version": 2, "a": 1.0, "non_finite": {"values": {"/a": "+inf"}}})
    assert to_document({"a": 1.0}) == {"format_version": FORMAT_VERSION, "a": 1.0}     # no block when all finite



def test_results_json_text_is_the_document_one_state_per_line():
    """dumps_document writes exactly the JSON data json.dumps would (keys included: true, null,
    numbers), refuses NaN and infinity, and puts each top-level key and each state on its own line."""
    from app.io.document import dumps_document
    doc = {"format_version": FORMAT_VERSION, "units": {"length": "mm"}, "empty": [], "none": {},
           "odd_keys": {True: 1, None: 2, 3: [1.5, {"x": [0.25]}]},
           "states": [{"index": k, "nodes": [{"u_N": -0.1 * k, "status": "slip"}] * 3} for k in range(4)]}
    text = dumps_document(doc)
    assert json.loads(text) == json.loads(json.dumps(doc))
    lines = text.splitlines()
    assert sum(1 for ln in lines if ln.startswith('  {"index": ')) == 4          # one line per state
    assert all(ln.startswith(" ") or ln in "{}" for ln in lines)
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError):
            dumps_document({"states": [{"x": bad}]})

def test_load_scene_errors_are_one_line():
    with pytest.raises(app.SceneError, match=r"^scene: .*mu") as err:
        app.load_scene({"name": "x", "system": {"type": "block"}, "mu": -1})
    assert "\n" not in str(err.value)
    with pytest.raises(app.SceneError, match="sweep"):
        app.run_study(app.load_scene(ROOT / "app/scenes/sweep_mu.yaml"))


@pytest.mark.slow
def test_block_results_json_keys_unchanged_and_api_matches_cli(tmp_path):
    """The shipped default scene through the CLI (with its pictures) and through the API."""
    scene = ROOT / "app/scenes/villechaise_block.yaml"
    proc = run_cli("run", str(scene), "-o", str(tmp_path / "out"), "-q")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "out" / "results.json").read_text())
    cli = from_document(doc)
    import sys
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from results_keys import key_paths
    finally:
        sys.path.pop(0)
    old_keys = set((DATA / "results_keys_villechaise_block.txt").read_text().split())
    new_keys = key_paths(cli)
    def answers(keys):   # key paths outside the solver evidence
        return {k for k in keys if not set(k.replace("[]", "").split(".")) & EVIDENCE}
    assert answers(old_keys) - answers(new_keys) == set(), "keys missing from results.json"
    added = {k for k in answers(new_keys) - answers(old_keys)
             if not k.startswith("scene_config.") and ".certificate." not in k    # the schema's echo; a proof's record
             and ".mceip_mu.onset." not in k and ".mceip_mu.complete." not in k}  # the two claims' records
    assert {k.rsplit(".", 1)[-1] for k in added} <= ADDED_KEYS, sorted(added)
    assert doc["format_version"] == FORMAT_VERSION and "non_finite" in doc

    r = app.run_study(app.load_scene(scene))
    assert str(r.final.min_mu()) == "1.7048"
    api = from_document(r.to_json())
    # the CLI also drew pictures and wrote ParaView files; the API computes only
    assert cli["outputs"]["files"] and api["outputs"]["files"] == []
    diffs = _differences(cli, api, skip=VOLATILE | {"outputs"})
    assert not diffs, "\n".join(diffs[:20])
    # a saved results.json reads back to the same typed result
    back = StudyResult.load(tmp_path / "out")
    assert back.final.min_mu() == r.final.min_mu() and len(back) == len(r) == 320
    assert back.first_instability().index == r.first_instability().index


def test_run_study_shows_progress_only_when_asked(capfd):
    """``app.run_study(scene)`` prints nothing; ``progress=True`` prints the command line's progress
    lines (standard error) with the same numbers."""
    import app
    scene = app.load_scene({"name": "p", "system": {"type": "block", "nx": 6, "ny": 3}, "mu": 1.1,
                            "analyses": ["necessary", "mceip_mu"]})
    quiet = app.run_study(scene)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    loud = app.run_study(scene, progress=True)
    out, err = capfd.readouterr()
    assert out == "" and "loading:" in err and f"analyses: {len(loud.states)}/{len(loud.states)} states" in err
    assert "MCEIP-mu:" in err
    assert [s.classification for s in loud.states] == [s.classification for s in quiet.states]
