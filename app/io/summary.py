"""Short human summary of a study printed at the end of a run."""
from __future__ import annotations

import pathlib

from app.io.result import MceipResult, StudyResult


def proof_word(analysis: MceipResult, slip_nodes: int | None = None) -> str:
    """What is proven about an MCEIP analysis: ``no slip node: nothing to prove`` at a state
    without unknowns (``slip_nodes`` 0: "no solution" holds trivially), ``proven on [0, cap]``
    when ``certified`` (the checker accepted every claim), ``onset proven; list ...`` when only
    the MCEIP-mu onset is, else ``found (not proven)`` with the proven lower bound when there is one."""
    if slip_nodes == 0:
        return "no slip node: no unknowns, nothing to prove"
    cert = analysis.certificate
    if analysis.certified:
        iv = [float(v) for v in cert.interval] if cert is not None and cert.interval else None
        where = f" on [{iv[0]:.6g}, {iv[1]:.6g}]" if iv and iv[1] > iv[0] else ""
        if cert is not None and cert.rigorous is False:
            return f"shown{where} in floating point, not a rigorous proof"
        return f"proven{where}"
    onset = getattr(analysis, "onset", None)
    if onset is not None and onset.proven:
        cap = None if cert is None else cert.cap
        where = f" below {float(cap):.6g}" if cap is not None else ""
        return f"onset proven; list of values{where} not proven"
    lb = None if cert is None else (cert.detail or {}).get("lower_bound")
    if lb:
        return f"found (not proven; proven: none below {float(lb):.6g})"
    return "found (not proven)"


def _patterns(m: MceipResult) -> str:
    """The solutions of an MCEIP as ``value (pattern)``, or why there are none."""
    vals = ", ".join(f"{float(x.value):.6g} ({''.join('S' if p == 'slip' else '-' for p in x.pattern)})"
                     for x in m.solutions)
    return vals or ("not searched" if m.result.startswith("not searched") else "none found")


def summary(study: StudyResult, outdir: pathlib.Path) -> str:
    """The summary of a study: the path, the first state where MCEIP-mu has a solution, the
    final state's analyses with what is proven, the warnings, failures, wall time per stage and
    the files written in ``outdir``."""
    lines = [f"scene '{study.scene}': {study.system}",
             f"  {len(study)} equilibrium state(s), {study.distinct_classifications} distinct "
             f"classification(s); path: {study.path.end}"]
    first_mu = study.first_instability()
    if first_mu is not None:
        lines.append(f"  MCEIP-mu first has a solution at state {first_mu.index} ({first_mu.counts()})")
    if not study.states:
        lines.append("  no equilibrium state: nothing to analyse")
        return "\n".join(lines)
    last = study.final
    lines.append(f"  final state {last.index}: {last.counts()}")
    for k, reason in last.failed.items():
        lines.append(f"    {k}: FAILED ({reason})")
    blocks = [getattr(last.analyses, k) for k in type(last.analyses).model_fields]
    for reason in sorted({str(v.reason) for v in blocks if v is not None and v.not_applicable}):
        lines.append(f"    stability analyses: {reason}")
    if last.necessary is not None:
        lines.append(f"    necessary condition (19): {'satisfied' if last.necessary.satisfied else 'not satisfied'}"
                     + (f" (min eig sym K* = {last.necessary.min_eig_K_sym:.6g})"
                        if last.necessary.min_eig_K_sym is not None else
                        " (min eig sym K* in [{:.6g}, {:.6g}])".format(*last.necessary.min_eig_K_sym_bounds)))
    if last.sufficient is not None:
        lam = last.max_lambda2()
        lines.append("    sufficient condition (17)-(18): "
                     + (f"satisfied, lambda^2 = {lam:.6g} 1/s^2" if lam is not None else "not satisfied"))
    if last.mceip_mu is not None:
        lines.append(f"    MCEIP-mu: {_patterns(last.mceip_mu)} [{proof_word(last.mceip_mu, last.classification.slip)}]")
    if last.mceip_lambda2 is not None:
        m = last.mceip_lambda2
        lines.append(f"    MCEIP-lambda^2 at mu = {m.mu}: {_patterns(m)} [{proof_word(m, last.classification.slip)}]")
    time_unit = study.units.time or "s"
    for tr in study.transient or ():
        lines.append("  " + transient_line(tr, time_unit))
    for w in study.warnings:
        lines.append(f"  WARNING: {w}")
    if study.failures:
        lines.append(f"  INCOMPLETE: {len(study.failures)} state(s) failed: "
                     + "; ".join(f"state {f.state} {f.analysis}: {f.reason}" for f in study.failures[:3]))
    lines.append(f"  wall time {study.wall_seconds:.2f} s; stages: "
                 + ", ".join(f"{s.name} {s.seconds:.2f} s" for s in study.stages))
    lines.append(f"  results: {outdir / 'results.json'}, {outdir / 'steps.csv'}")
    files = [] if study.outputs is None else study.outputs.files
    if files:
        parts = [str(outdir / "report.md")] if "report.md" in files else []
        for k in ("plots", "screenshots", "paraview"):
            n = sum(f.startswith(k + "/") for f in files)
            if n:
                parts.append(f"{n} file(s) in {outdir / k}")
        lines.append("  outputs: " + ", ".join(parts))
    for note in [] if study.outputs is None else study.outputs.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def transient_line(tr, time_unit: str = "s") -> str:
    """One line for the dynamics from a state (results.json ``transient``)."""
    head = f"dynamics from state {tr.state} at mu = {tr.mu:g}: "
    if tr.skipped:
        return head + f"not run ({tr.skipped})"
    last = tr.runs[-1] if tr.runs else None
    if tr.predicted_rate is not None:
        measured = "no growth" if tr.measured_rate is None else f"{tr.measured_rate:.6g} 1/{time_unit}"
        err = "" if last is None or last.relative_error is None else f" ({100 * last.relative_error:.2g} % off"
        order = "" if tr.observed_order is None else f", observed order {tr.observed_order:.2f}"
        return (head + f"the divergence mode grows at {measured}, predicted lambda = "
                f"{tr.predicted_rate:.6g} 1/{time_unit}{err}{order}{')' if err else ''} at dt = {last.dt:.3g} "
                f"{time_unit}; {last.status_changes} status change(s)")
    if last is None:
        return head + "no divergence mode (MCEIP-lambda^2: none at this mu)"
    fs = last.final_status
    start = "a push of the slip nodes" if tr.start is None or tr.start.startswith("a static") else tr.start
    return (head + f"no divergence mode (MCEIP-lambda^2: none at this mu); from {start} over "
            f"{tr.t_end:.3g} {time_unit}: amplitude at most {last.amplitude_max_ratio:.3g} x the start, at the end "
            f"{fs.get('free', 0)} free / {fs.get('stick', 0)} stick / {fs.get('slip', 0)} slip, total energy "
            f"change {last.total_energy_change:.3g} (never above its start by more than "
            f"{last.total_energy_rise:.2g})")
