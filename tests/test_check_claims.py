"""``python -m app check`` verifies the claims of results.json, not the words of a proof log.

Each test forges or damages a copy of one genuine results folder (the 8 x 4 block, whose last
state has a critical mu at 1.7075 and an earlier classification none below 11) as someone
handing over results might, and asserts that ``check`` refuses the claim (exit status 1) or the
folder (exit status 2, one ``error:`` line) instead of re-verifying it.
"""
from __future__ import annotations

import io
import json
import os
import shutil
import zipfile

import numpy as np
import pytest
from conftest import run_cli, run_cli_here

BLOCK = "name: chk\nsystem: {type: block, nx: 8, ny: 4}\nmu: 1.1\nanalyses: [mceip_mu]\n"


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """A results folder of a real run, and the state holding the onset at 1.7075."""
    tmp = tmp_path_factory.mktemp("genuine")
    (tmp / "s.yaml").write_text(BLOCK)
    p = run_cli_here("run", str(tmp / "s.yaml"), "-o", str(tmp / "out"), "-q")
    assert p.returncode == 0, p.stderr
    res = json.loads((tmp / "out" / "results.json").read_text())
    last = res["states"][-1]
    assert last["analyses"]["mceip_mu"]["onset"]["value"] < 2.0 and last["analyses_shared_with"] is None
    return tmp / "out", last["index"]


@pytest.fixture
def folder(genuine, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(genuine[0], out)
    return out, genuine[1]


def _results(out):
    return json.loads((out / "results.json").read_text())


def _save_results(out, res):
    (out / "results.json").write_text(json.dumps(res))


def _pencil(out, k):
    with np.load(out / "proofs" / f"state_{k}.npz") as z:
        return z["A0"], z["A1"], json.loads(str(z["log"]))


def _save_proof(out, k, A0, A1, log):
    buf = io.BytesIO()
    np.savez(buf, A0=A0, A1=A1, log=np.array(json.dumps(log)))
    (out / "proofs" / f"state_{k}.npz").write_bytes(buf.getvalue())


def _deny_onset(res, k):
    """results.json edited to claim that state ``k`` has no critical mu in [0, 11] (it has one at 1.7)."""
    a = res["states"][k]["analyses"]["mceip_mu"]
    a["onset"] = {"proven": True, "status": "proven: no critical mu in [0, 11]", "value": None, "enclosure": None}
    a["complete"] = {"proven": True, "status": "proven: 0 critical value(s) in [0, 11]", "interval": [0.0, 11.0],
                     "count": 0}
    a["solutions"] = []
    a["certified"] = True
    a["certificate"]["detail"]["lower_bound"] = 11.0


def _check(out):
    p = run_cli_here("check", str(out))
    assert "Traceback" not in p.stdout + p.stderr
    return p


def test_the_genuine_folder_is_verified(folder):
    out, _ = folder
    p = _check(out)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "NOT VERIFIED" not in p.stdout and " claims re-verified" in p.stdout


def test_forged_pairs_that_exclude_every_support_are_refused(folder):
    """A log whose pairs put every index in a pair with itself proves 'no critical mu' for any pencil:
    the pairs come from the classification (no zero-reaction node here: none), not from the log."""
    import app
    out, k = folder
    A0, A1, _ = _pencil(out, k)
    forged = app.mceip_mu(A0, A1, cap=11.0, pairs=[(i, i) for i in range(A0.shape[0])])
    assert forged.onset.proven and forged.onset.value is None       # the forgery passes the prover's own checker
    _save_proof(out, k, A0, A1, forged.log.to_json())
    res = _results(out)
    _deny_onset(res, k)
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1, p.stdout
    assert f"state {k} " in p.stdout and "NOT VERIFIED" in p.stdout and "pairs" in p.stdout


@pytest.mark.parametrize("cap", [1e-300, 1.0])
def test_a_log_with_a_smaller_cap_does_not_prove_a_claim_on_0_11(folder, cap):
    import app
    out, k = folder
    A0, A1, _ = _pencil(out, k)
    small = app.mceip_mu(A0, A1, cap=cap)
    assert small.onset.proven and small.onset.value is None and small.all.proven
    _save_proof(out, k, A0, A1, small.log.to_json())
    res = _results(out)
    _deny_onset(res, k)
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1 and "no critical mu in [0, 11]: proven only up to" in p.stdout, p.stdout
    assert "complete list on [0, 11]: the proof covers" in p.stdout


def test_a_claimed_value_outside_its_proven_enclosure_is_refused(folder):
    out, k = folder
    res = _results(out)
    a = res["states"][k]["analyses"]["mceip_mu"]
    a["onset"]["value"] = 1.5
    a["onset"]["enclosure"] = [1.4, 1.6]
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1 and "onset mu = 1.5: proven enclosure [1.7075" in p.stdout, p.stdout


def test_a_missing_critical_value_in_a_complete_list_is_refused(folder):
    out, k = folder
    res = _results(out)
    a = res["states"][k]["analyses"]["mceip_mu"]
    a["solutions"] = [d for d in a["solutions"] if not d.get("certified")][:0]
    a["complete"]["count"] = 0
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1 and "values claimed" in p.stdout, p.stdout


def test_a_deleted_proof_file_or_folder_fails_the_claims_that_need_it(folder):
    out, k = folder
    (out / "proofs" / f"state_{k}.npz").unlink()
    p = _check(out)
    assert p.returncode == 1 and f"proof file proofs/state_{k}.npz missing" in p.stdout, p.stdout
    shutil.rmtree(out / "proofs")
    p = _check(out)
    assert p.returncode == 1
    n = sum(1 for line in p.stdout.splitlines() if "missing: NOT VERIFIED" in line)
    assert n >= 5, p.stdout                      # every classification with slip nodes


def test_a_state_sharing_a_pencil_of_another_classification_is_refused(folder):
    out, k = folder
    res = _results(out)
    st = res["states"][k - 1]
    assert st["analyses_shared_with"] is not None
    st["analyses_shared_with"] = k                # claims the last state's pencil, but it is another classification
    st["analyses"] = res["states"][k]["analyses"]
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1 and "whose classification differs" in p.stdout, p.stdout


def test_a_fifo_or_a_symlink_in_place_of_a_proof_is_never_opened(folder, tmp_path):
    out, k = folder
    path = out / "proofs" / f"state_{k}.npz"
    path.unlink()
    os.mkfifo(path)
    p = run_cli("check", str(out), timeout=120)          # a process of its own: a hang would be a timeout
    assert p.returncode == 1 and "not a regular file" in p.stdout, p.stdout + p.stderr
    path.unlink()
    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(out / "proofs", elsewhere)
    shutil.rmtree(out / "proofs")
    (out / "proofs").symlink_to(elsewhere)
    p = _check(out)
    assert p.returncode == 1 and "symbolic link" in p.stdout, p.stdout


def _npy(a):
    buf = io.BytesIO()
    np.lib.format.write_array(buf, a, allow_pickle=False)
    return buf.getvalue()


def test_a_huge_array_header_is_refused_before_allocating(folder):
    out, k = folder
    path = out / "proofs" / f"state_{k}.npz"
    with zipfile.ZipFile(path, "w") as zf:
        hdr = io.BytesIO()
        np.lib.format.write_array_header_1_0(hdr, {"descr": "<f8", "fortran_order": False, "shape": (10**6, 10**6)})
        magic = np.lib.format.magic(1, 0)
        for name in ("A0", "A1"):
            zf.writestr(f"{name}.npy", magic + hdr.getvalue() + np.zeros(8).tobytes())
        zf.writestr("log.npy", _npy(np.array("{}")))
    p = _check(out)
    assert p.returncode == 1 and "refused" in p.stdout, p.stdout
    # a pickled object is never loaded either
    with zipfile.ZipFile(path, "w") as zf:
        buf = io.BytesIO()
        np.lib.format.write_array(buf, np.array([{"x": 1}], dtype=object), allow_pickle=True)
        zf.writestr("A0.npy", buf.getvalue())
        zf.writestr("A1.npy", buf.getvalue())
        zf.writestr("log.npy", _npy(np.array("{}")))
    p = _check(out)
    assert p.returncode == 1 and "Python objects" in p.stdout, p.stdout


def test_the_quadratic_proof_ignores_the_logs_max_s(tmp_path):
    """A curved obstacle's per-support proof is re-run only up to the run's own 8 slip nodes: a log
    asking for ``max_s: 24`` on a 20 x 20 pencil (2^20 supports in exact arithmetic) is refused at once."""
    scene = ("name: q\nsystem: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1],\n"
             "         obstacle: {type: circle, radius: 10.0, side: outside}, normal_reaction: 3000.0}\n"
             "mu: 2.5\nanalyses: [mceip_mu]\n")
    (tmp_path / "q.yaml").write_text(scene)
    out = tmp_path / "out"
    assert run_cli_here("run", str(tmp_path / "q.yaml"), "-o", str(out), "-q").returncode == 0
    assert _check(out).returncode == 0
    res = _results(out)
    k = next(st["index"] for st in res["states"] if (st["analyses"].get("mceip_mu") or {}).get("quadratic")
             and st["analyses_shared_with"] is None and st["classification"]["slip"] > 0)
    s = 20
    rng = np.random.default_rng(1)
    arrays = {n: rng.standard_normal((s, s)) for n in ("A0", "A1", "A2")}
    buf = io.BytesIO()
    np.savez(buf, **arrays, log=np.array(json.dumps({"format": "mceip-mu-quadratic/1", "cap": 2.5, "max_s": 24,
                                                      "pairs": []})))
    (out / "proofs" / f"state_{k}.npz").write_bytes(buf.getvalue())
    for st in res["states"]:
        if st["index"] == k or st["analyses_shared_with"] == k:
            st["classification"]["slip"] = s
            st["nodes"] = [{**st["nodes"][0], "id": i, "status": "slip"} for i in range(s)]
    _save_results(out, res)
    p = run_cli("check", str(out), timeout=300)
    assert p.returncode == 1 and "re-run up to 8 slip nodes" in p.stdout, p.stdout + p.stderr


@pytest.mark.parametrize("text, needle", [
    ("[1, 2]", "expected an object"),
    ("[" * 100_000 + "]" * 100_000, "nested too deep"),
    ('{"format_version": 3, "states": 5}', "states"),
    ('{"format_version": 3, "states": [{"index": 0, "classification": {"slip": 1}, "analyses": "x"}]}', "analyses"),
    ('{"format_version": 3, "states": [{"index": "a"}]}', "index"),
    ('{"format_version": 3, "states": [{"index": 0, "classification": {"slip": 1}, "analyses": {"mceip_mu": '
     '{"onset": {"proven": true, "value": "x"}}}}]}', "onset.value"),
    ("not json", "not valid JSON"),
    ("\xff\xfe", "not valid JSON"),
])
def test_malformed_results_json_is_one_line(folder, text, needle):
    out, _ = folder
    (out / "results.json").write_bytes(text.encode("latin-1"))
    p = _check(out)
    assert p.returncode == 2 and p.stdout == "", p.stdout + p.stderr
    assert len(p.stderr.splitlines()) == 1 and p.stderr.startswith("error: ") and needle in p.stderr, p.stderr


def test_results_json_that_is_huge_a_fifo_or_a_symlink_is_refused_unread(folder, tmp_path):
    out, _ = folder
    path = out / "results.json"
    with open(path, "r+b") as f:
        f.truncate(3 * 2**30)                      # 3 GB, sparse: nothing is written
    p = _check(out)
    assert p.returncode == 2 and "is over the" in p.stderr and "not read" in p.stderr, p.stderr
    path.unlink()
    os.mkfifo(path)
    p = run_cli("check", str(out), timeout=120)
    assert p.returncode == 2 and "a FIFO, not a regular file" in p.stderr, p.stderr
    path.unlink()
    (tmp_path / "other.json").write_text("{}")
    path.symlink_to(tmp_path / "other.json")
    p = _check(out)
    assert p.returncode == 2 and "symbolic link" in p.stderr, p.stderr


def test_a_state_whose_counts_deny_its_slip_nodes_is_refused(folder):
    """'No slip node, no critical mu' needs no pencil: the classification's counts must agree with
    its nodes' statuses."""
    out, k = folder
    res = _results(out)
    st = res["states"][k]
    st["classification"]["slip"] = 0
    _save_results(out, res)
    p = _check(out)
    assert p.returncode == 1 and "its classification counts 0 slip" in p.stdout, p.stdout


def _mutations(log: dict, rng) -> list[dict]:
    """Damaged copies of a proof log: a field of a node given another type, an index out of range, a
    witness cut short, a root or cap changed."""
    out = []
    nodes = log["nodes"]
    for _ in range(12):
        bad = json.loads(json.dumps(log))
        n = bad["nodes"][int(rng.integers(len(nodes)))]
        key = str(rng.choice([k for k in n if k != "id"] or ["kind"]))
        values = [None, "x", -1, 10**9, [10**9], [[1, 2]], {"a": 1}, 1e308, True]
        n[key] = values[int(rng.integers(len(values)))] if key != "kind" else "leaf"
        out.append(bad)
    for key, value in (("onset_root", 10**9), ("all_roots", ["x"]), ("cap", "11"), ("nodes", {"0": 1}),
                       ("scale_exp", 10**6), ("s", -1), ("onset_witness", {"U": [99], "mu": 1.7, "h": 1, "x": []})):
        out.append({**log, key: value})
    return out


def test_a_damaged_proof_log_is_a_claim_not_verified_never_a_traceback(folder):
    """Damaged logs of the onset state, from the checker's point of view: every one either still proves
    the claims or is reported as not verified (exit 1), never a traceback."""
    from app.io.check import check_folder
    out, k = folder
    A0, A1, log = _pencil(out, k)
    rng = np.random.default_rng(7)
    verdicts = []
    for bad in _mutations(log, rng):
        _save_proof(out, k, A0, A1, bad)
        report = check_folder(out)                # raises on a traceback
        state = next(c for c in report.states if c.state == k)
        verdicts.append(state.ok)
        if not state.ok:
            assert state.failed and all(isinstance(f, str) for f in state.failed)
    assert verdicts.count(False) >= 16, verdicts       # most damage is caught (some touch unused fields)
