"""A library of certified MCEIP-mu instances from finite-element contact problems (docs/instances.md).

    .venv/bin/python scripts/instance_library.py [-o output/instances] [--no-large]

Each instance is the condensed pencil ``A(mu) = A0 + mu A1`` (``+ mu^2 A2`` on a curved obstacle)
of one equilibrium state of a study, exported by ``python -m app export --states ... --pencils-only``
with the answers the app proved for it (its onset and its complete list of critical values up to
a cap, each re-verified by the independent checker). The studies run here, with the commands a
user runs; the instances and an index (``index.json``, ``README.md``) are written into a new
folder. ``--no-large`` leaves out the 10^5-DOF study (about a minute and 3 GB of memory).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: (instance folder, what it is, the scene (file or document), its folder for relative paths, states)
def _library(large: bool) -> list[tuple[str, str, dict, pathlib.Path, list[str]]]:
    block = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
    block.update(analyses=["mceip_mu"])
    block.pop("outputs", None)
    left = json.loads(json.dumps(block))
    left["system"]["pattern"] = "left"
    curved = yaml.safe_load((ROOT / "app/scenes/gmsh/half_disk_cylinder.yaml").read_text())
    curved.update(analyses=["mceip_mu"])
    curved.pop("outputs", None)
    out = [("block-20x10", "the paper's block, 20 x 10 crossed mesh (820 DOFs), mu = 1.1", block,
            ROOT / "app/scenes", ["first_mceip_mu", "final"]),
           ("block-left-20x10", "the paper's block on the 'left' mesh of its Fig. 2 (one diagonal per cell)",
            left, ROOT / "app/scenes", ["first_mceip_mu", "final"]),
           ("half-disk-cylinder", "a half disk pressed into a rigid cylinder (curved obstacle: quadratic pencil)",
            curved, ROOT / "app/scenes/gmsh", ["first_mceip_mu", "final"])]
    if large:
        big = json.loads(json.dumps(block))
        big["system"].update(nx=224, ny=112)
        out.append(("block-224x112", "the paper's block, 224 x 112 crossed mesh (100,576 DOFs)", big,
                    ROOT / "app/scenes", ["final"]))
    return out


def _app(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "app", *args], check=True, cwd=ROOT)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=str(ROOT / "output" / "instances"), help="a new folder")
    ap.add_argument("--no-large", action="store_true", help="leave out the 10^5-DOF study")
    args = ap.parse_args(argv)
    out = pathlib.Path(args.output)
    if out.exists():
        print(f"error: {out} exists: give a new folder with -o", file=sys.stderr)
        return 2
    index = []
    with tempfile.TemporaryDirectory() as tmp:
        t = pathlib.Path(tmp)
        staging = t / "library"
        staging.mkdir()
        for name, what, scene, base, states in _library(not args.no_large):
            scene_file = base / f".instance-{name}.yaml"       # beside the scene: its relative paths hold
            try:
                scene_file.write_text(yaml.safe_dump(scene, sort_keys=False))
                _app("run", str(scene_file), "-o", str(t / name), "-q")
                sel = [x for s in states for x in ("--states", s)]
                _app("export", str(t / name), "--matrices", "--pencils-only", "-o", str(staging / name),
                     "--scene", str(scene_file), *sel)
            finally:
                scene_file.unlink(missing_ok=True)
            for c in json.loads((staging / name / "index.json").read_text())["classifications"]:
                a = json.loads((staging / name / c["folder"] / "answers.json").read_text())
                m = a["mceip_mu"] or {}
                onset, complete = m.get("onset") or {}, m.get("complete") or {}
                index.append({"instance": f"{name}/{c['folder']}", "source": what, "s": a["slip_nodes"],
                              "quadratic": a["quadratic"], "classification": a["classification"],
                              "critical_values": sorted(x["value"] for x in m.get("solutions", [])),
                              "onset": onset.get("value"), "onset_enclosure": onset.get("enclosure"),
                              "onset_proven": bool(onset.get("proven")),
                              "list_proven_on": complete.get("interval") if complete.get("proven") else None})
        (staging / "index.json").write_text(json.dumps(index, indent=1))
        (staging / "README.md").write_text(_readme(index))
        shutil.move(str(staging), str(out))
    print(f"{out}: {len(index)} instances (index.json, README.md)")
    return 0


def _readme(index: list[dict]) -> str:
    lines = ["# Certified MCEIP-mu instances", "",
             "Made by scripts/instance_library.py; the problem and the files are described in the app's "
             "docs/instances.md. \"Proven list\": every critical value in the interval, and no other there "
             "(the onset's enclosure is given where it is proven); other values found are not part of the "
             "claim.", "",
             "| instance | s | pencil | proven on | proven list | onset enclosure | other values found (not proven) |",
             "|---|---|---|---|---|---|---|"]
    for e in index:
        on, enc = e["list_proven_on"], e["onset_enclosure"]
        inside = [v for v in e["critical_values"] if on and on[0] <= v <= on[1]]
        onset_value = e["onset"] if e["onset_proven"] else None
        above = [v for v in e["critical_values"] if v not in inside and v != onset_value]
        listed = (", ".join(f"{v:.10g}" for v in inside[:6]) + (f", ... ({len(inside)} values)" if len(inside) > 6
                                                                else "")) if inside else "none"
        onset = f"[{enc[0]:.12g}, {enc[1]:.12g}]" if e["onset_proven"] and enc else "-"
        lines.append(f"| {e['instance']} | {e['s']} | {'quadratic' if e['quadratic'] else 'linear'} | "
                     f"{f'[{on[0]:g}, {on[1]:g}]' if on else 'not proven'} | {listed if on else '-'} | {onset} | "
                     f"{', '.join(f'{v:.6g}' for v in above) or '-'} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
