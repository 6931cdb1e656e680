"""results.json and steps.csv (docs/method.md section 6), written atomically by rank 0."""
from __future__ import annotations

import csv
import io
import math
import os
import pathlib
import tempfile

from app.io.document import dumps_document
from app.io.result import StateResult, StudyResult


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


def append_line(path: pathlib.Path, text: str, complete_last: bool = False) -> None:
    """Append ``text`` to the log file ``path`` (created with the usual mode), never through a
    symbolic link (``O_NOFOLLOW``) nor into a file that is not a regular file or has other hard
    links (OSError). ``complete_last``: first end a last line cut short (by a killed run) with a
    newline."""
    import errno
    import stat
    flags = os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags, file_mode())
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
            raise OSError(errno.EPERM, "not a regular file of its own (a FIFO, a device or a hard link): "
                                       "not written", str(path))
        if complete_last and st.st_size and os.pread(fd, 1, st.st_size - 1) != b"\n":
            text = "\n" + text
        if text:
            os.write(fd, text.encode("utf-8"))
    finally:
        os.close(fd)


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


def _cell(v: float | None):
    """A number of steps.csv: empty when absent or not finite (results.json writes those as null)."""
    return "" if v is None or not math.isfinite(v) else float(v)


def step_row(st: StateResult) -> dict:
    """The steps.csv row of one typed state."""
    load, c = st.load.to_dict(), st.classification
    return {
        "index": st.index, "phase": load.get("phase", ""), "step": load.get("step", ""),
        # a loading program's parameters (a body from Gmsh: motions, loads, gravity), name=value;...
        "load_parameters": ";".join(f"{k}={v!r}" for k, v in (load.get("parameters") or {}).items()),
        "u_x_CD": load.get("u_x", ""), "u_y_CD": load.get("u_y", ""),
        "normal_resultant": load.get("normal_resultant", ""),
        "tangential_resultant": load.get("tangential_resultant", ""),
        "n_free": c.free, "n_zero": c.zero, "n_stick": c.stick, "n_slip": c.slip,
        "necessary_min_eig_K_sym": "" if st.necessary is None else _cell(st.necessary.min_eig_K_sym),
        "necessary_satisfied": "" if st.necessary is None else st.necessary.satisfied,
        "sufficient_max_lambda2": _cell(st.max_lambda2()),
        "mceip_mu_min": _cell(st.min_mu()),
        "mceip_mu_count": "" if st.mceip_mu is None else len(st.mceip_mu.solutions),
        "mceip_lambda2_max": "" if st.mceip_lambda2 is None else _cell(st.mceip_lambda2.max()),
        "shared_with": "" if st.analyses_shared_with is None else st.analyses_shared_with,
        "analysis_seconds": "" if st.analysis_seconds is None else st.analysis_seconds,
    }


def steps_csv(study: StudyResult) -> str:
    """The text of steps.csv: a header (units from the study's ``units``, :func:`csv_header`) and
    one row per state (:func:`step_row`)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow([csv_header(c, STEP_UNITS.get(c), study.units.to_dict()) for c in STEP_COLUMNS])
    w.writerows([row[c] for c in STEP_COLUMNS] for row in map(step_row, study.states))
    return buf.getvalue()


def write_results(study: StudyResult, outdir: pathlib.Path, written_one=None) -> list[pathlib.Path]:
    """Write steps.csv then results.json (last: its presence marks a complete run) of the typed
    ``study`` (results.json is :meth:`StudyResult.to_json`); ``written_one()`` is called after
    each (progress). The MCEIP-mu proofs (app/io/proofs.py) are written before, while the results
    still hold the pencils."""
    outdir.mkdir(parents=True, exist_ok=True)
    done = written_one or (lambda: None)
    atomic_write(outdir / "steps.csv", steps_csv(study))
    done()
    atomic_write(outdir / "results.json", dumps_document(study.to_json()))
    done()
    return [outdir / "steps.csv", outdir / "results.json"]
