"""Compare two results.json files value by value (issue 14: "answers identical").

Every number must agree to ``--rtol`` (relative, absolute below 1), every string, bool and list
length exactly; wall-clock fields (any key containing ``seconds``, the ``stages`` list, run
metadata such as dates and paths) are skipped. Differences are grouped by the key they occur
under, so evidence that legitimately varies with the code path (solver iteration counts,
SCIP's node count) is easy to tell apart from answers.

    .venv/bin/python benchmarks/compare_results.py BEFORE/results.json AFTER/results.json [--rtol 1e-8]
    .venv/bin/python benchmarks/compare_results.py --answers BEFORE AFTER   # the answers only
    .venv/bin/python benchmarks/compare_results.py --write-answers RESULTS.json OUT.json

``--answers`` compares what :func:`answers` extracts (the values, patterns, classifications and
certificate statuses; BEFORE and AFTER may each be a results.json or a file written by
``--write-answers``). The tests compare the default study and a shipped example so
(tests/test_default_answers.py, tests/test_gmsh_examples.py).

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


def answers(doc: dict) -> dict:
    """The answers of a study in a compact form: per state its classification, the status and
    slip sign of every contact node and the state it shares its analyses with; per distinct
    classification (key: the state index) the necessary condition (19) (satisfied, smallest
    eigenvalues), the sufficient condition (17)-(18) (satisfied, lambda^2 values), every solution
    of MCEIP-mu and MCEIP-lambda^2 (value, mode x_Ts, pattern) and the certificate statuses
    (certified; for MCEIP-mu the onset and the complete list proven); a failed analysis as
    ``{"failed": true}``. ``doc``: results.json data (``app.io.document.from_document``)."""
    out: dict = {"states": [], "analyses": {}}
    for s in doc["states"]:
        out["states"].append({"index": s["index"], "classification": s["classification"],
                              "status": "".join(n["status"][1] for n in s["nodes"]),   # t(ick), l(ip), r(ee), e(ro)
                              "signs": [n["sign"] for n in s["nodes"]],
                              "shared_with": s.get("analyses_shared_with")})
        if s.get("analyses_shared_with") is not None:
            continue
        d = {}
        for name, a in s.get("analyses", {}).items():
            if a.get("failed"):
                d[name] = {"failed": True}
            elif name == "necessary":
                d[name] = {k: a[k] for k in ("satisfied", "min_eig_K_sym", "min_eig_M_sym")}
            elif name == "sufficient":
                d[name] = {"satisfied": a["satisfied"], "lambda2": a["lambda2"]}
            elif "solutions" in a:
                d[name] = {"solutions": [{"value": x["value"], "x_Ts": x["x_Ts"], "pattern": x["pattern"]}
                                         for x in a["solutions"]],
                           "certified": a.get("certified")}
                for claim in ("onset", "complete"):
                    if isinstance(a.get(claim), dict):
                        d[name][f"{claim}_proven"] = a[claim].get("proven")
        out["analyses"][str(s["index"])] = d
    return out


def _read(path: str) -> dict:
    """A results.json (any format version, infinities as floats) or an answers file."""
    root = str(pathlib.Path(__file__).resolve().parents[1])
    if root not in sys.path:
        sys.path.insert(0, root)
    from app.io.document import from_document
    with open(path) as f:
        data = json.load(f)
    if "format_version" not in data and set(data) == {"states", "analyses"}:
        return data
    data = from_document(data)
    data.pop("format_version", None)
    return data


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--answers", action="store_true", help="compare the answers only (see answers())")
    ap.add_argument("--write-answers", action="store_true",
                    help="write the answers of BEFORE (a results.json) to the file AFTER")
    args = ap.parse_args()
    a = _read(args.before)
    if args.write_answers:
        pathlib.Path(args.after).write_text(json.dumps(answers(a), indent=0) + "\n")
        return 0
    b = _read(args.after)
    if args.answers:
        a = a if set(a) == {"states", "analyses"} else answers(a)
        b = b if set(b) == {"states", "analyses"} else answers(b)
    diffs = compare(a, b, args.rtol)
    if not diffs:
        print(f"identical: every value to {args.rtol:g}, every string and list (timings skipped)")
        return 0
    for key, where in sorted(diffs.items(), key=lambda kv: str(kv[0])):
        print(f"{key}: {len(where)} difference(s), e.g. {where[:2]}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
