"""results.json and steps.csv (docs/method.md section 6), written atomically by rank 0."""
from __future__ import annotations

import csv
import io
import os
import pathlib
import tempfile

from app.io.document import dumps_document, to_document
from app.io.result import StateResult


def _umask() -> int:
    """The process umask (read without changing it where /proc allows, else set and restored)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """The mode a plain ``open(path, "w")`` gives: 0666 minus the umask (as the plots and report get)."""
    return 0o666 & ~_umask()


def atomic_write(path: pathlib.Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename, so
    that ``path`` is either absent, the old file, or complete (never half-written).

    The file gets the usual mode (0666 minus the umask), not mkstemp's 0600. A full disk raises
    OSError(ENOSPC) and leaves no temporary file behind."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, file_mode())
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        pathlib.Path(tmp).unlink(missing_ok=True)
        raise


STEP_COLUMNS = ["index", "phase", "u_x_CD", "u_y_CD", "normal_resultant", "tangential_resultant",
                "n_free", "n_zero", "n_stick", "n_slip", "necessary_min_eig_K_sym", "necessary_satisfied",
                "sufficient_max_lambda2", "mceip_mu_min", "mceip_mu_count", "mceip_lambda2_max",
                "shared_with", "analysis_seconds", "step", "load_parameters"]

#: the quantity (a key of results.json ``units``) of the steps.csv columns that have a unit
STEP_UNITS = {"u_x_CD": "length", "u_y_CD": "length", "normal_resultant": "force", "tangential_resultant": "force",
              "sufficient_max_lambda2": "lambda2", "mceip_lambda2_max": "lambda2"}


def csv_header(column: str, quantity: str | None, units: dict) -> str:
    """A CSV column's header: ``column [unit]`` with the unit of ``quantity`` in the scene's
    ``units`` (``u_x_CD [mm]``, ``u_x_CD [m]``), the bare name when it has none (or is ``1``)."""
    unit = units.get(quantity) if quantity else None
    return f"{column} [{unit}]" if unit and unit != "1" else column


def step_rows(results: dict) -> list[dict]:
    """One row per state for steps.csv."""
    rows = []
    for st in results["states"]:
        a = st.get("analyses", {})
        load = st.get("load", {})
        res = StateResult.from_dict(st)
        mu_sols = [] if res.mceip_mu is None else [float(v) for v in res.mceip_mu.values]
        l2_sols = [] if res.mceip_lambda2 is None else [float(v) for v in res.mceip_lambda2.values]
        suff = a.get("sufficient", {}).get("lambda2", [])
        nec = a.get("necessary", {})
        c = st["classification"]
        rows.append({
            "index": st["index"], "phase": load.get("phase", ""), "step": load.get("step", ""),
            # a loading program's parameters (a body from Gmsh: motions, loads, gravity), name=value;...
            "load_parameters": ";".join(f"{k}={v!r}" for k, v in (load.get("parameters") or {}).items()),
            "u_x_CD": load.get("u_x", ""), "u_y_CD": load.get("u_y", ""),
            "normal_resultant": load.get("normal_resultant", ""),
            "tangential_resultant": load.get("tangential_resultant", ""),
            "n_free": c["free"], "n_zero": c["zero"], "n_stick": c["stick"], "n_slip": c["slip"],
            "necessary_min_eig_K_sym": nec.get("min_eig_K_sym", ""),
            "necessary_satisfied": nec.get("satisfied", ""),
            "sufficient_max_lambda2": max(suff) if suff else "",
            "mceip_mu_min": min(mu_sols) if mu_sols else "",
            "mceip_mu_count": len(mu_sols) if "solutions" in (a.get("mceip_mu") or {}) else "",
            "mceip_lambda2_max": max(l2_sols) if l2_sols else "",
            "shared_with": "" if st.get("analyses_shared_with") is None else st["analyses_shared_with"],
            "analysis_seconds": st.get("analysis_seconds", ""),
        })
    return rows


def steps_csv(results: dict) -> str:
    """The text of steps.csv: a header (units from results ``units``, :func:`csv_header`) and one
    row per state (:func:`step_rows`)."""
    units = results.get("units") or {}
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow([csv_header(c, STEP_UNITS.get(c), units) for c in STEP_COLUMNS])
    w.writerows([row[c] for c in STEP_COLUMNS] for row in step_rows(results))
    return buf.getvalue()


def write_results(results: dict, outdir: pathlib.Path, written_one=None) -> list[pathlib.Path]:
    """Write steps.csv then results.json (last: its presence marks a complete run); ``written_one()``
    is called after each (progress). The MCEIP-mu proofs (app/io/proofs.py) are written before,
    while the results still hold the pencils."""
    outdir.mkdir(parents=True, exist_ok=True)
    done = written_one or (lambda: None)
    atomic_write(outdir / "steps.csv", steps_csv(results))
    done()
    atomic_write(outdir / "results.json", dumps_document(to_document(results)))
    done()
    return [outdir / "steps.csv", outdir / "results.json"]
