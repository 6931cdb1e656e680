"""Draw what the scene's ``outputs`` ask for (plots, screenshots, report) from the results alone.

Runs on rank 0, after the study (``python -m app run``) or later on saved results
(``python -m app render RESULTS_DIR``): it never recomputes anything. The fields the screenshots
need were saved by the study's field stage (app/io/fields.py) in ``fields/fields.npz``.
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import pathlib
import sys
import tempfile
import time

from app.common.errors import write_limit
from app.common.stages import Stages
from app.io.result import OutputsRecord, Stage, StudyResult
from app.io.select import select_states

log = logging.getLogger(__name__)

PICTURE_STAGES = ("plots (matplotlib)", "screenshots (pyvista)", "report")


def outputs_config(study: StudyResult) -> dict:
    """The scene's ``outputs`` section as the study records it (``scene_config``), empty if none."""
    return study.scene_config.get("outputs") or {}


def wants_pictures(study: StudyResult) -> bool:
    """Whether the scene's ``outputs`` ask for plots, screenshots or the report."""
    return _asks_pictures(outputs_config(study))


def _asks_pictures(cfg: dict) -> bool:
    return bool(cfg.get("plots") or cfg.get("screenshots") or cfg.get("report"))


@contextlib.contextmanager
def _survive(what: str, notes: list[str]):
    """A picture that cannot be drawn is a note, not a lost study: the results are still written."""
    try:
        yield
    except Exception as err:          # noqa: BLE001 - any drawing failure
        if write_limit(err) is not None:
            raise                     # a full disk (or ulimit -f) ends the run as anywhere else (exit status 4)
        log.warning("%s failed", what, exc_info=True)
        notes.append(f"{what} failed ({type(err).__name__}: {err}); the results are complete: "
                     f"redraw with python -m app render")


def _stages(base: list[Stage], stages: Stages) -> list[Stage]:
    """The study's stages ``base`` followed by the picture stages timed so far."""
    return base + [Stage.model_validate(r) for r in stages.as_list()]


def draw_outputs(study: StudyResult, outdir: pathlib.Path, progress=None,
                 fields: pathlib.Path | None = None) -> tuple[StudyResult, list[str]]:
    """Draw every picture asked for into ``outdir``, a folder holding no earlier pictures (a run's
    staging folder, or the new folder of a redraw). ``fields``: the screenshots' fields.npz
    (default ``outdir/fields/fields.npz``).

    Returns the study with the drawing recorded, and the files drawn (relative to ``outdir``).
    The record: in ``outputs``, the files drawn added to ``files``, the notes of what was left out
    or failed added to ``notes``, the ``pictured_states``; in ``stages``, the picture stages of
    this drawing in place of those of an earlier one; ``versions`` (with the report) when the study
    has none. A study whose scene asks for no picture comes back with its ``outputs`` record only
    (``notes`` and ``files`` present).

    ``study`` should be the study as read back from results.json (:func:`draw_after_run`) so that
    a run and a later render draw the same pictures.
    """
    fields = outdir / "fields" / "fields.npz" if fields is None else fields
    cfg = outputs_config(study)
    record = study.outputs or OutputsRecord()
    record = record.model_copy(update={"notes": list(record.notes), "files": list(record.files)})
    if not wants_pictures(study):
        return study.model_copy(update={"outputs": record}), []
    stages = Stages()
    # the run's stages; picture stages of an earlier drawing are replaced by this one's
    base = [s for s in study.stages if s.name not in PICTURE_STAGES]
    pictured, notes = select_states(study.states, cfg.get("states") or ["final"])
    notes = [n for n in notes if n not in record.notes]
    plot_files, shot_files = [], []
    want_plots = bool(cfg.get("plots"))
    want_shots = bool(cfg.get("screenshots")) and not record.fields_not_applicable    # e.g. no mesh (matrices)
    if "dolfinx.cpp" in sys.modules:
        # after a run: two child processes draw the plots and the screenshots at the same time
        if want_plots or want_shots:
            plot_files, shot_files = _draw_in_children(study, pictured, cfg, outdir, fields, progress, stages,
                                                       notes, want_plots, want_shots)
    else:                    # no DOLFINx here (e.g. python -m app render): drawn in this process
        if want_plots:
            with stages(PICTURE_STAGES[0]), _survive("plots", notes):
                from app.plot.plots import draw_plots
                plot_files, n = draw_plots(study, pictured, outdir / "plots")
                notes += n
        if want_shots:
            with stages(PICTURE_STAGES[1]), _survive("screenshots", notes):
                from app.plot.screenshots import draw_screenshots
                shot_files, n = draw_screenshots(study, pictured, cfg["screenshots"], outdir / "screenshots",
                                                 fields, progress)
                notes += n
    for n in notes:
        log.warning("%s", n)
    notes = record.notes + notes      # every note of the study, a failure of the report added below
    record = record.model_copy(update={"notes": notes, "pictured_states": pictured})
    drawn = [p.relative_to(outdir).as_posix() for p in plot_files + shot_files]
    if cfg.get("report"):
        from app.io.report import versions, write_report
        # the report lists the stages before it, and the versions
        study = study.model_copy(update={"versions": study.versions if study.versions is not None else versions(),
                                         "stages": _stages(base, stages), "outputs": record})
        with stages(PICTURE_STAGES[2]), _survive("report", notes):
            rep = write_report(study, outdir, pictured, plot_files, shot_files, notes)
            drawn.append(rep.relative_to(outdir).as_posix())
    record = record.model_copy(update={"notes": notes, "files": list(dict.fromkeys(record.files + drawn))})
    study = study.model_copy(update={"stages": _stages(base, stages), "outputs": record})
    for st in stages.as_list():
        log.info("%s: %.2f s", st["name"], st["seconds"])
    log.info("pictures: drew %d file(s)", len(drawn))
    return study, drawn


def _draw_in_children(study: StudyResult, pictured: list[int], cfg: dict, outdir: pathlib.Path,
                      fields: pathlib.Path, progress, stages: Stages, notes: list[str], want_plots: bool,
                      want_shots: bool) -> tuple[list, list]:
    """Plots and screenshots drawn by two child processes at once (app/plot/worker.py: VTK cannot
    run next to DOLFINx; the children started by :func:`prestarted` are already warm). Each
    picture stage records the drawing time its child reports; the notes of the children are added
    to ``notes``.

    Both children read one job file, JSON data: :func:`app.plot.screenshots.job_of`'s job, whose
    ``results`` is the results.json document (each child reads the study back from it), and the
    plots' folder ``plots_dir``."""
    from app.plot import worker
    from app.plot.screenshots import job_of, resolution_arg
    t0 = time.perf_counter()
    shots_cfg = cfg.get("screenshots") or {}
    job = None
    running, out = [], {}
    try:
        with _survive("plots and screenshots", notes):
            data = job_of(study, pictured, shots_cfg, outdir / "screenshots", fields, progress)
            # a new file of this run's own (exclusive create), removed below
            fd, name = tempfile.mkstemp(dir=outdir, prefix=".pictures-job-", suffix=".json")
            job = pathlib.Path(name)
            with os.fdopen(fd, "w") as f:
                json.dump({**data, "plots_dir": str(outdir / "plots")}, f)
            for stage, kind, want, arg in ((PICTURE_STAGES[1], "screenshots", want_shots, resolution_arg(shots_cfg)),
                                           (PICTURE_STAGES[0], "plots", want_plots, "")):
                if want:
                    running.append((stage, worker.take(kind, arg).submit(job)))
            worker.close_unused()
            for stage, child in running:
                files, n, seconds = child.wait()
                notes += n
                out[stage] = files
                stages.records[stage] = {"name": stage, "count": 1,
                                         "seconds": time.perf_counter() - t0 if seconds is None else seconds}
    except BaseException:       # interrupted: the drawing is abandoned with the run
        for _, child in running:
            child.close(kill=True)
        raise
    finally:
        for _, child in running:
            child.close()
        if job is not None:
            job.unlink(missing_ok=True)
    log.info("plots and screenshots: %.2f s after the run (drawn at the same time by two processes)",
             time.perf_counter() - t0)
    return out.get(PICTURE_STAGES[0], []), out.get(PICTURE_STAGES[1], [])


def _draws(scene) -> bool:
    """The scene's outputs ask for plots or screenshots (drawn by child processes after a run)."""
    outputs = getattr(scene, "outputs", None)
    return outputs is not None and bool(outputs.plots or outputs.screenshots is not None)


@contextlib.contextmanager
def prestarted(scene, comm):
    """Around a study whose results rank 0 will draw: on rank 0, the drawing processes of the
    plots and the screenshots are started first, so that they import matplotlib and VTK and warm
    up while the study runs; those not used are stopped at the end."""
    # the children draw only in a process that has loaded DOLFINx (:func:`draw_outputs`): a meshed
    # system's study loads it; a mesh-less system's pictures (particles, matrices) are drawn here
    meshed = getattr(scene.system, "has_fields", False)
    if comm.rank != 0 or not _draws(scene) or not (meshed or "dolfinx.cpp" in sys.modules):
        yield
        return
    outputs = scene.outputs
    from app.plot import worker
    try:
        if outputs.plots:
            worker.prestart("plots")
        if outputs.screenshots is not None and meshed:
            from app.plot.screenshots import resolution_arg
            worker.prestart("screenshots", resolution_arg(outputs.screenshots.model_dump(mode="json")))
        yield
    except BaseException:       # interrupted or failed: the children's warm-up is not waited for
        worker.close_unused(kill=True)
        raise
    finally:
        worker.close_unused()


def read_back(study: StudyResult) -> StudyResult:
    """The study as ``render`` reads it from its results.json: what is kept in memory only (mode
    vectors, proofs' pencils) left out, every value as the file gives it back."""
    from app.io.document import from_document
    return StudyResult.from_dict(from_document(json.loads(json.dumps(study.to_json(), allow_nan=False))))


def draw_after_run(study: StudyResult, outdir: pathlib.Path, progress=None) -> StudyResult:
    """After a run (rank 0): the study with the pictures drawn if the scene asks (their files,
    notes and stages recorded in it, :func:`draw_outputs`).

    The drawing works on the study as it will be read back from results.json (:func:`read_back`),
    so a later ``render`` draws exactly the same pictures; that is the study returned.
    """
    if not wants_pictures(study):
        return study
    result, _ = draw_outputs(read_back(study), outdir, progress)
    return result
