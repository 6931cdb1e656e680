"""The one driver behind ``python -m app run``, sweeps and refinement studies: run a study,
draw what the scene asks for, write the results, and turn the outcome into an exit status.

* :func:`run_and_write` -- :func:`app.study.run.study` (collective), then on rank 0 the pictures
  (app/plot/pictures.py) and ``results.json``/``steps.csv`` (app/io/results.py);
* :func:`commit` -- every rank has written: rank 0 moves the staged folder into place;
* :func:`exit_status` -- 0 ok, 3 some states failed (:data:`app.common.errors.EXIT_INCOMPLETE`).

A loading that cannot be followed raises :class:`app.common.errors.UnreachableLoad` identically on every
rank; callers turn it into one ``error:`` line (:func:`loading_error`).
"""
from __future__ import annotations

import pathlib
from typing import Any, Optional

from app.common.errors import EXIT_INCOMPLETE, EXIT_OK
from app.common.progress import Progress
from app.common.waiting import sleep_until
from app.io.result import StudyResult
from app.scene.schema import Scene


def run_and_write(scene: Scene, comm, outdir: pathlib.Path, progress: Optional[Progress] = None,
                  extra: Optional[dict[str, Any]] = None) -> StudyResult:
    """Run ``scene`` on ``comm`` (MPI collective), then rank 0 draws and writes into ``outdir``.

    ``extra``: fields of the result set before it is written (e.g. a sweep case's identity,
    ``sweep_case``). Returns the typed result (on rank 0 with the pictures drawn recorded).
    """
    from app.plot.pictures import prestarted
    from app.study.run import study
    progress = progress or Progress(enabled=False)
    with prestarted(scene, comm):     # rank 0: the drawing processes warm up during the study
        # outdir: where the scene's field outputs (if any) go, written while the system is alive
        result = study(scene, comm, progress, outdir=outdir)
        if comm.rank == 0:
            from app.io.proofs import count_proofs, write_proofs
            from app.io.results import write_results
            from app.plot.pictures import draw_after_run  # plots, screenshots, report (if asked)
            if extra:
                result = result.model_copy(update=extra)
            n = count_proofs(result)
            if n:                              # a large study stores hundreds of MB of pencils
                bar = progress.bar(n, "writing proofs", unit="file")
                write_proofs(result, outdir, lambda: bar.update(1))   # before the drawing drops the pencils
                bar.close()
            # the drawing records its files, notes and stages in the result
            result = draw_after_run(result, outdir, progress)
            bar = progress.bar(2, "writing results", unit="file")
            write_results(result, outdir, lambda: bar.update(1))
            bar.close()
    return result


def commit(folder, comm) -> Optional[pathlib.Path]:
    """Wait until every rank has written (MPI collective), then rank 0 commits ``folder``
    (app/io/folder.py: the staged results replace the target atomically). Returns the final
    folder on rank 0, None elsewhere."""
    sleep_until(comm.Ibarrier().Test)        # MPI collective; the others sleep while rank 0 draws and writes
    return folder.commit() if comm.rank == 0 else None


def exit_status(failures: list) -> int:
    """0 when nothing failed, 3 when some state or level failed (listed in the results)."""
    return EXIT_INCOMPLETE if failures else EXIT_OK


def loading_error(source: str, err: BaseException) -> str:
    """The one-line message of an :class:`app.common.errors.UnreachableLoad` for scene ``source``."""
    key = getattr(err, "key", "loading")
    return f"{source}: {key}: {err}" if key else f"{source}: {err}"
