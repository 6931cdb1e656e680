"""Print the key paths of a results.json, one a line, sorted (the format skeleton).

``python scripts/results_keys.py output/villechaise-block/results.json``. Dictionary keys are
joined with ``.``, list items are ``[]``; the dictionaries keyed by data (``by_method``: SNES
methods, ``x_c``: zero-node labels) stop the descent. tests/test_results_format.py compares the
skeleton of a new run with the one committed in tests/data/ (taken from the previous release):
a change of the results.json format shows up there and must be deliberate (then regenerate it
with this script and raise ``FORMAT_VERSION`` in app/io/document.py if keys were removed or
changed meaning).
"""
from __future__ import annotations

import json
import pathlib
import sys

DATA_KEYED = ("by_method", "x_c")


def key_paths(obj, prefix: str = "") -> set[str]:
    """Every key path of a JSON document (see the module docstring)."""
    out: set[str] = set()
    if isinstance(obj, dict):
        for k, v in obj.items():
            p = f"{prefix}.{k}" if prefix else str(k)
            out.add(p)
            if k not in DATA_KEYED:
                out |= key_paths(v, p)
    elif isinstance(obj, list):
        for v in obj:
            out |= key_paths(v, prefix + "[]")
    return out


def main(argv: list[str]) -> int:
    """Print the skeleton of the results.json named on the command line."""
    doc = json.loads(pathlib.Path(argv[0]).read_text(encoding="utf-8"))
    print("\n".join(sorted(key_paths(doc))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
