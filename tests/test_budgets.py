"""Budgets count work, never seconds (issue 33): what decides "proven" is the same on any machine.

The proofs' budgets are proof-tree nodes (``settings.mcp.certify_onset_nodes``,
``certify_all_nodes``, ``certify_onset_nodes_large``, ``certify_quadratic_nodes``) and, for the
quadratic per-support proof, its ``2^8 - 1`` supports. A clock that runs 100 times fast in the
provers' modules (a machine 100 times slower, as far as any deadline can tell) must give the same
statuses and values at every state of the default study and of a curved Gmsh body (whose
quadratic branch and bound runs about 1 s a state here: a 60 s deadline read on that clock
expires after 0.6 s, which is how the former time budgets failed this test).

The ``*_seconds`` keys remain a wall-clock safety stop, off by default: when one ends a proof the
status says "stopped by the time limit" and the study warns, never "not proven within budget";
old scenes that set them still validate.
"""
from __future__ import annotations

import importlib
import sys
import time
import types

import pytest
import yaml
from conftest import ROOT, run_scene

from app.scene.schema import default_scene_path, parse_scene

#: the fast clock's speed: 100 s of its time per real second
SPEED = 100.0
#: the modules of the provers and of the study around them (each reads ``time.*`` through its
#: module global ``time``, which the fast clock replaces)
PROVERS = ("app.analyses.mceip_mu", "app.analyses.mceip_mu.prover.branch", "app.analyses.mceip_mu.prover.claims",
           "app.analyses.mceip_mu.kernel.closing", "app.analyses.mceip_mu.prover.leaves", "app.analyses.mceip_mu.state",
           "app.analyses.mceip_mu.quadratic.problem", "app.analyses.mceip_mu.quadratic.bb",
           "app.analyses.mceip_mu.quadratic.proof", "app.analyses.mceip_mu.candidates", "app.analyses.runner",
           "app.analyses.zero_nodes", "app.study.scheduler", "app.analyses.mceip_lambda2.analysis",
           "app.analyses.mceip_lambda2.exact", "app.analyses.mceip_lambda2.bounds", "app.study.run")


def _fast_time(speed: float) -> types.SimpleNamespace:
    """A stand-in for the ``time`` module whose ``perf_counter``, ``monotonic`` and ``time`` (and
    their ``_ns`` forms) run ``speed`` times fast from now; everything else is the real module's."""
    fake = types.SimpleNamespace(**{k: getattr(time, k) for k in dir(time) if not k.startswith("__")})
    for name in ("perf_counter", "monotonic", "time"):
        real, real_ns = getattr(time, name), getattr(time, name + "_ns")
        t0, t0_ns = real(), real_ns()
        setattr(fake, name, lambda real=real, t0=t0: t0 + speed * (real() - t0))
        setattr(fake, name + "_ns", lambda real_ns=real_ns, t0_ns=t0_ns: t0_ns + int(speed * (real_ns() - t0_ns)))
    return fake


@pytest.fixture
def fast_clock(monkeypatch):
    """Run the provers' clocks ``SPEED`` times fast: every ``app.analyses`` and ``app.study``
    module that imported ``time`` sees the fast one (the named provers at least)."""
    for name in PROVERS:
        importlib.import_module(name)
    fake = _fast_time(SPEED)
    patched = []
    for name, mod in list(sys.modules.items()):
        if name.startswith(("app.analyses", "app.study")) and getattr(mod, "time", None) is time:
            monkeypatch.setattr(mod, "time", fake)
            patched.append(name)
    missing = [m for m in PROVERS if m not in patched and "time" in vars(sys.modules[m])]
    assert not missing, missing
    assert {"app.analyses.mceip_mu.prover.branch", "app.analyses.mceip_mu.quadratic.bb"} <= set(patched)
    real0, fast0 = time.perf_counter(), fake.perf_counter()
    time.sleep(0.02)
    assert (fake.perf_counter() - fast0) > 0.5 * SPEED * (time.perf_counter() - real0)
    return fake


def _statuses(results: dict) -> list[tuple]:
    """Per state: MCEIP-mu's onset and complete-list flags, values and statuses, the certificate's
    status and every solution's value, pattern and certified flag."""
    out = []
    for st in results["states"]:
        m = st["analyses"].get("mceip_mu")
        if m is None:
            out.append((st["index"], None))
            continue
        on, al = m.get("onset") or {}, m.get("complete") or {}
        out.append((st["index"], m.get("certified"), on.get("proven"), on.get("status"), on.get("value"),
                    al.get("proven"), al.get("status"), al.get("count"), (m.get("certificate") or {}).get("status"),
                    tuple((float(x["value"]), tuple(x["pattern"]), x.get("certified")) for x in m["solutions"])))
    return out


def _default_study() -> dict:
    scene = yaml.safe_load(default_scene_path().read_text())
    scene.pop("outputs", None)
    return scene


def _curved_gmsh(monkeypatch) -> dict:
    """The shipped half disk in a concave seat (a curved obstacle: quadratic MCEIP-mu, the branch
    and bound above 8 slip nodes), run from its folder (its .geo file is relative)."""
    folder = ROOT / "app" / "scenes" / "gmsh"
    monkeypatch.chdir(folder)
    scene = yaml.safe_load((folder / "half_disk_seat.yaml").read_text())
    scene.pop("outputs", None)
    return scene


@pytest.mark.slow
@pytest.mark.parametrize("which", ["default study", "default study, large-s path", "curved gmsh body"])
def test_a_slow_machine_proves_the_same(which, monkeypatch, request):
    """Every state's MCEIP-mu statuses, values and proven flags are those of the normal run when
    the provers' clock runs 100 times fast (deadlines, had they decided, would have expired). The
    large-s path (reduced search, ``certify_onset_nodes_large``) is forced above 8 slip nodes on the
    default study; it had a 5 s budget, 0.05 s on the fast clock."""
    if which == "curved gmsh body":
        scene = _curved_gmsh(monkeypatch)
    else:
        scene = _default_study()
        if which.endswith("large-s path"):
            scene["settings"] = {"mcp": {"search_full_max": 8}}
    normal = run_scene(scene)
    ref = _statuses(normal)
    assert any(s[1:3] == (True, True) for s in ref if s[1:] != (None,))       # proofs ran and were accepted
    if which == "curved gmsh body":
        assert any("branch and bound" in ((st["analyses"].get("mceip_mu") or {}).get("certificate") or {})
                   .get("method", "") for st in normal["states"])            # the quadratic branch and bound ran
    request.getfixturevalue("fast_clock")
    slow = _statuses(run_scene(scene))
    assert slow == ref
    assert not any("stopped by the time limit" in str(s) for s in slow)


def test_old_time_keys_validate_and_mean_a_safety_stop():
    """``certify_seconds: 60`` (and the other former time budgets) still validate; the defaults are
    no time limit at all."""
    old = parse_scene({**_default_study(), "settings": {"mcp": {"certify_seconds": 60, "certify_all_seconds": 30,
                                                                "certify_seconds_large": 0}}})
    assert (old.settings.mcp.certify_seconds, old.settings.mcp.certify_all_seconds,
            old.settings.mcp.certify_seconds_large) == (60.0, 30.0, 0.0)
    new = parse_scene(_default_study()).settings.mcp
    assert (new.certify_seconds, new.certify_all_seconds, new.certify_seconds_large) == (None, None, None)


def test_a_safety_stop_is_reported_as_such():
    """A safety stop that ends proofs says "stopped by the time limit" in the statuses of
    results.json and in the study's warnings (the summary prints them), never "not proven within
    budget"; the states it did not reach in time are never reported proven for it."""
    scene = _default_study()
    scene["settings"] = {"mcp": {"certify_seconds": 1e-9}}
    res = run_scene(scene)
    stopped = [s for s in _statuses(res) if s[1:] != (None,) and "stopped by the time limit" in str(s[8])]
    assert stopped, "no proof was stopped by a 1 ns time limit"
    for s in stopped:
        assert s[1] is False and s[8] != "not proven within budget"
        assert s[2] is False or s[8].startswith("onset proven")
    assert any("stopped by the time limit" in w for w in res["warnings"])
