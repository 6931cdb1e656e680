"""The yardstick of a side-by-side benchmark: a module of the app as it is at another git commit.

``baseline_module("main", "app/loading/contact.py")`` imports that file's text at ``main`` (read
with ``git show``) as a module of its own, next to today's ``app`` (its own imports resolve to
today's modules), so old and new code run in one process on the same inputs.
"""
from __future__ import annotations

import importlib.util
import pathlib
import subprocess
import sys
import tempfile
import types

ROOT = pathlib.Path(__file__).resolve().parents[1]


def baseline_module(ref: str, path: str) -> types.ModuleType:
    """The module at ``path`` (relative to the repository) as committed at ``ref``."""
    text = subprocess.run(["git", "show", f"{ref}:{path}"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout
    name = f"baseline_{ref.replace('/', '_')}_{pathlib.Path(path).stem}"
    folder = pathlib.Path(tempfile.mkdtemp(prefix="baseline-"))
    file = folder / f"{name}.py"
    file.write_text(text)
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
