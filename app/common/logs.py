"""Logging set-up of the command line (``--log-level``).

The app logs under the ``app`` logger. Third-party libraries are shown from WARNING up (all of
them at DEBUG): DOLFINx's JIT compiler goes through setuptools, which raises the root logger to
INFO while it compiles and would otherwise print "running build_ext" and the compiler lines.
Under MPI, ranks other than 0 log warnings and errors only, prefixed with their rank.
"""
from __future__ import annotations

import logging
import sys


class _Filter(logging.Filter):
    def __init__(self, level: int):
        super().__init__()
        self.level = level

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING or self.level <= logging.DEBUG:
            return True
        return record.name == "app" or record.name.startswith("app.")


def setup_logging(level_name: str = "WARNING", rank: int = 0) -> None:
    """Log to stderr at ``level_name`` (``"DEBUG"``, ``"INFO"``, ...) on rank 0 and at WARNING and
    above, prefixed ``[rank N]``, on the other ranks; other libraries' records below WARNING are
    shown only at DEBUG. Replaces the root logger's handlers."""
    level = getattr(logging, str(level_name).upper())
    app_level = level if rank == 0 else max(level, logging.WARNING)
    handler = logging.StreamHandler(sys.stderr)
    prefix = "" if rank == 0 else f"[rank {rank}] "
    handler.setFormatter(logging.Formatter(prefix + "%(levelname)s: %(message)s"))
    handler.addFilter(_Filter(app_level))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(app_level)
    logging.getLogger("app").setLevel(app_level)
