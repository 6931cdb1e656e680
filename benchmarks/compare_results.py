"""Compare two results.json files value by value (issue 14: "answers identical").

Every number must agree to ``--rtol`` (relative, absolute below 1), every string, bool and list
length exactly; wall-clock fields (any key containing ``seconds``, the ``stages`` list, run
metadata such as dates and paths) are skipped. Differences are grouped by the key they occur
under, so evidence that legitimately varies with the code path (solver iteration counts,
SCIP's node count) is easy to tell apart from answers.

    .venv/bin/python benchmarks/compare_results.py BEFORE/results.json AFTER/results.json [--rtol 1e-8]

Both files are read with ``app.io.document.from_document``, so files of older formats compare
with newer ones under the newer key names (format 3: ``path.normal_displacement_mm`` is
``normal_displacement``, ...). Exit status 0 when nothing differs, 1 otherwise.
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import pathlib
import sys

#: keys whose values are wall-clock times or describe the run rather than its answers
SKIP_KEYS = {"stages", "created", "started", "finished", "date", "host", "hostname", "output", "outdir",
             "command", "argv", "python", "versions", "machine", "environment", "pid"}


def compare(a, b, rtol: float) -> dict[str, list[str]]:
    """Differences of ``b`` from ``a``: key name -> list of "path: a vs b"."""
    diffs: dict[str, list[str]] = collections.defaultdict(list)

    def walk(x, y, path: str, key: str) -> None:
        if isinstance(key, str) and (key in SKIP_KEYS or "seconds" in key):
            return
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y), key=str):
                if k not in x or k not in y:
                    diffs[f"only in {'after' if k in y else 'before'}: {k}"].append(path)
                else:
                    walk(x[k], y[k], f"{path}/{k}", k)
        elif isinstance(x, list) and isinstance(y, list):
            if len(x) != len(y):
                diffs[key].append(f"{path}: length {len(x)} vs {len(y)}")
                return
            for i, (u, v) in enumerate(zip(x, y)):
                walk(u, v, f"{path}[{i}]", key)
        elif (isinstance(x, (int, float)) and isinstance(y, (int, float))
              and not isinstance(x, bool) and not isinstance(y, bool)):
            if x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)):
                return
            if not abs(x - y) <= rtol * max(1.0, abs(x), abs(y)):
                diffs[key].append(f"{path}: {x!r} vs {y!r}")
        elif x != y:
            diffs[key].append(f"{path}: {str(x)[:60]!r} vs {str(y)[:60]!r}")

    walk(a, b, "", "")
    return diffs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rtol", type=float, default=1e-8)
    args = ap.parse_args()
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    from app.io.document import from_document  # any format version, infinities as floats
    with open(args.before) as f:
        a = from_document(json.load(f))
    with open(args.after) as f:
        b = from_document(json.load(f))
    a.pop("format_version", None)
    b.pop("format_version", None)
    diffs = compare(a, b, args.rtol)
    if not diffs:
        print(f"identical: every value to {args.rtol:g}, every string and list (timings skipped)")
        return 0
    for key, where in sorted(diffs.items(), key=lambda kv: str(kv[0])):
        print(f"{key}: {len(where)} difference(s), e.g. {where[:2]}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
