"""A results folder that never looks complete when it is not.

A run writes into a hidden staging folder beside the target (``.NAME.partial-PID``) and moves
it into place only when everything is written; an existing results folder is either kept (the
run refuses to start) or replaced by two renames, as the user chose with ``--overwrite``. An
interrupted run leaves the previous results untouched and at most a ``.partial`` folder.
"""
from __future__ import annotations

import os
import pathlib
import shutil
import time


class ResultsFolder:
    """Staging and atomic replacement of a results folder (used on rank 0 only)."""

    def __init__(self, final: pathlib.Path, overwrite: bool):
        self.final = pathlib.Path(final)
        self.overwrite = overwrite
        tag = f"{os.getpid()}-{int(time.time())}"
        self.staging = self.final.parent / f".{self.final.name}.partial-{tag}"
        self._old = self.final.parent / f".{self.final.name}.old-{tag}"

    def check(self) -> str | None:
        """A one-line problem with the target, or None."""
        if self.final.exists() and not self.final.is_dir():
            return f"cannot create the output folder {self.final}: a file of that name exists"
        if self.final.is_dir() and any(self.final.iterdir()) and not self.overwrite:
            return (f"the output folder {self.final} already holds results; "
                    f"use --overwrite to replace them, or choose another folder with -o")
        try:
            self.final.parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            return f"cannot create the output folder {self.final}: {err.strerror or err}"
        if not os.access(self.final.parent, os.W_OK):
            return f"the output folder {self.final} cannot be written (parent not writable)"
        return None

    def open(self) -> pathlib.Path:
        self.staging.mkdir(parents=False, exist_ok=False)
        return self.staging

    def commit(self) -> pathlib.Path:
        """Move the staged results into place (replacing the old ones in two renames)."""
        if self.final.exists():
            os.replace(self.final, self._old)
        os.replace(self.staging, self.final)
        shutil.rmtree(self._old, ignore_errors=True)
        return self.final

    def abort(self) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)
