"""``python -m app check RESULTS``: every claim re-verified from the stored pencils, for the
flat obstacle (proof logs, independent checker) and the curved one (the exact quadratic proof run
again); a tampered file is rejected with exit status 1. (The first check of each test is a new
process, as a user runs it; the runs and the re-checks run in this one.)"""
from __future__ import annotations

import io
import json

import numpy as np
from conftest import run_cli, run_cli_here

BLOCK = "name: chk\nsystem: {type: block, nx: 8, ny: 4}\nmu: 1.1\nanalyses: [mceip_mu]\n"
CURVED = ("name: chkc\nsystem: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1],\n"
          "         obstacle: {type: circle, radius: 10.0, side: outside}, normal_reaction: 3000.0}\n"
          "mu: 2.5\nanalyses: [mceip_mu]\n")


def _run(tmp_path, text, name):
    scene = tmp_path / f"{name}.yaml"
    scene.write_text(text)
    out = tmp_path / name
    p = run_cli_here("run", str(scene), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    return out


def res_states(out):
    """The states of ``out`` claiming something proven about MCEIP-mu (here: every state)."""
    return json.loads((out / "results.json").read_text())["states"]


def _rewrite(path, **changes):
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    buf = io.BytesIO()
    np.savez_compressed(buf, **data)
    path.write_bytes(buf.getvalue())


def test_check_reverifies_and_rejects_tampering(tmp_path):
    out = _run(tmp_path, BLOCK, "flat")
    files = sorted((out / "proofs").glob("state_*.npz"))
    assert files
    p = run_cli("check", str(out))
    assert p.returncode == 0, p.stdout + p.stderr
    assert f"({len(res_states(out))} states, {len(files)} proof files)" in p.stdout and "NOT VERIFIED" not in p.stdout
    # a pencil changed after the run: the log no longer proves what results.json claims
    target = max(files, key=lambda f: np.load(f)["A0"].shape[0])
    with np.load(target) as z:
        A1 = z["A1"].copy()
    _rewrite(target, A1=A1 - 5.0 * np.abs(A1).max() * np.eye(A1.shape[0]))
    p = run_cli_here("check", str(out))
    assert p.returncode == 1 and "NOT VERIFIED" in p.stdout, p.stdout + p.stderr


def test_check_proves_a_curved_obstacle_again(tmp_path):
    out = _run(tmp_path, CURVED, "curved")
    res = json.loads((out / "results.json").read_text())
    mm = [s["analyses"]["mceip_mu"] for s in res["states"] if (s.get("analyses") or {}).get("mceip_mu")]
    assert any(m.get("quadratic") and m["certified"] for m in mm)
    files = sorted((out / "proofs").glob("state_*.npz"))
    assert files and all("A2" in np.load(f).files for f in files)
    p = run_cli("check", str(out))
    assert p.returncode == 0, p.stdout + p.stderr
    assert f"({len(res_states(out))} states, {len(files)} proof files)" in p.stdout and "NOT VERIFIED" not in p.stdout
    # another curvature term: the proven list no longer matches results.json
    with np.load(files[-1]) as z:
        A2 = z["A2"].copy()
    _rewrite(files[-1], A2=A2 + np.eye(A2.shape[0]) * (1.0 + np.abs(A2).max()))
    p = run_cli_here("check", str(out))
    assert p.returncode == 1, p.stdout + p.stderr
