"""Short human summary of a study printed at the end of a run."""
from __future__ import annotations

import pathlib

from app.io.result import StudyResult


def proof_word(analysis: dict) -> str:
    """What is proven about an analysis: ``proven on [0, cap]`` when ``certified`` (the checker
    accepted every claim), ``onset proven; list ...`` when only the MCEIP-mu onset is, else
    ``found (not proven)`` with the proven lower bound when there is one."""
    if analysis.get("certified"):
        cert = analysis.get("certificate") or {}
        iv = cert.get("interval")
        iv = [float(v) for v in iv] if iv else iv
        where = f" on [{iv[0]:.6g}, {iv[1]:.6g}]" if iv and iv[1] > iv[0] else ""
        if cert.get("rigorous", True) is False:
            return f"shown{where} in floating point, not a rigorous proof"
        return f"proven{where}"
    onset = analysis.get("onset") or {}
    if onset.get("proven"):
        cap = (analysis.get("certificate") or {}).get("cap")
        where = f" below {float(cap):.6g}" if cap is not None else ""
        return f"onset proven; list of values{where} not proven"
    lb = ((analysis.get("certificate") or {}).get("detail") or {}).get("lower_bound")
    if lb:
        return f"found (not proven; proven: none below {float(lb):.6g})"
    return "found (not proven)"


def summary(results: dict, outdir: pathlib.Path) -> str:
    """The summary of a study from its results dictionary: the path, the first state where MCEIP-mu
    has a solution, the final state's analyses with what is proven, the warnings, failures, wall
    time per stage and the files written in ``outdir``."""
    states = results["states"]
    lines = [f"scene '{results['scene']}': {results['system']}",
             f"  {len(states)} equilibrium state(s), {results['distinct_classifications']} distinct "
             f"classification(s); path: {results['path'].get('end', '')}"]
    first_mu = StudyResult.from_dict(results).first_instability()
    if first_mu is not None:
        c = first_mu.classification
        lines.append(f"  MCEIP-mu first has a solution at state {first_mu.index} "
                     f"({c['stick']} stick / {c['slip']} slip / {c['free']} free)")
    if not states:
        lines.append("  no equilibrium state: nothing to analyse")
        return "\n".join(lines)
    last = states[-1]
    c = last["classification"]
    lines.append(f"  final state {last['index']}: {c['stick']} stick / {c['slip']} slip / {c['free']} free"
                 + (f" / {c['zero']} zero" if c["zero"] else ""))
    a = {k: v for k, v in last["analyses"].items() if not v.get("failed") and not v.get("not_applicable")}
    for k, v in last["analyses"].items():
        if v.get("failed"):
            lines.append(f"    {k}: FAILED ({v['reason']})")
    na = sorted({v["reason"] for v in last["analyses"].values() if v.get("not_applicable")})
    for reason in na:
        lines.append(f"    stability analyses: {reason}")
    if "necessary" in a:
        lines.append(f"    necessary condition (19): {'satisfied' if a['necessary']['satisfied'] else 'not satisfied'}"
                     f" (min eig sym K* = {a['necessary']['min_eig_K_sym']:.6g})")
    if "sufficient" in a:
        lam = a["sufficient"]["lambda2"]
        lines.append("    sufficient condition (17)-(18): " + (f"satisfied, lambda^2 = {max(lam):.6g} 1/s^2" if lam else "not satisfied"))
    for key, name in (("mceip_mu", "MCEIP-mu"), ("mceip_lambda2", "MCEIP-lambda^2")):
        if key in a:
            sols = a[key]["solutions"]
            vals = ", ".join(f"{s['value']:.6g} ({''.join('S' if p == 'slip' else '-' for p in s['pattern'])})"
                             for s in sols) or ("not searched" if str(a[key].get("result", "")).startswith("not searched")
                                                else "none found")
            extra = f" at mu = {a[key]['mu']}" if key == "mceip_lambda2" else ""
            lines.append(f"    {name}{extra}: {vals} [{proof_word(a[key])}]")
    for w in results.get("warnings", []):
        lines.append(f"  WARNING: {w}")
    if results["failures"]:
        lines.append(f"  INCOMPLETE: {len(results['failures'])} state(s) failed: "
                     + "; ".join(f"state {f['state']} {f.get('analysis', '')}: {f['reason']}" for f in results["failures"][:3]))
    lines.append(f"  wall time {results['wall_seconds']:.2f} s; stages: "
                 + ", ".join(f"{s['name']} {s['seconds']:.2f} s" for s in results["stages"]))
    lines.append(f"  results: {outdir / 'results.json'}, {outdir / 'steps.csv'}")
    files = (results.get("outputs") or {}).get("files") or []
    if files:
        parts = [str(outdir / "report.md")] if "report.md" in files else []
        for k in ("plots", "screenshots", "paraview"):
            n = sum(f.startswith(k + "/") for f in files)
            if n:
                parts.append(f"{n} file(s) in {outdir / k}")
        lines.append("  outputs: " + ", ".join(parts))
    for note in (results.get("outputs") or {}).get("notes") or []:
        lines.append(f"  note: {note}")
    return "\n".join(lines)
