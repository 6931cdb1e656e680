#!/usr/bin/env bash
# One set-up for every machine (developer, CI, Docker): Debian's FEniCSx stack with apt-get,
# then a virtual environment at the repository root that sees Debian's packages and adds
# what Debian lacks. Idempotent: does nothing slow when everything is already in place.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

debs=(python3-dolfinx-real python3-petsc4py-real python3-slepc4py-real python3-gmsh
      python3-mpi4py openmpi-bin python3-venv python3-pip python3-scipy python3-yaml
      python3-h5py libopenblas0-pthread make git
      bubblewrap                                      # the sandbox of a user's Gmsh files (app/systems/gmsh/sandbox.py)
      python3-siconos                                 # the reference for nonsmooth dynamics (tests/test_transient.py)
      libegl1 libegl-mesa0 libgl1-mesa-dri)   # off-screen pyvista (EGL, no X server) for the screenshots
missing=()
for p in "${debs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
fi

py=/usr/bin/python3
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv (system site packages)"
  "$py" -m venv --system-site-packages .venv
fi

# Python packages: exactly the versions in requirements.lock (`make lock` refreshes it), checked
# against their hashes, with --no-deps so that pip resolves nothing itself and never replaces
# Debian's compiled numpy/scipy/h5py/PyYAML/mpi4py (scripts/debian_pins.py; the compiled
# PETSc/DOLFINx modules break with numpy 2: "numpy.dtype size changed"). The app itself is then
# installed in editable mode, built with Debian's setuptools and wheel (no build isolation, so
# nothing unpinned is downloaded).
pins=.venv/debian-pins.txt
"$py" scripts/debian_pins.py > "$pins"
stamp=.venv/.setup-stamp
want="$(cat pyproject.toml requirements.lock "$pins" | sha256sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing the locked Python packages into .venv (requirements.lock)"
  .venv/bin/python -m pip install -q --disable-pip-version-check --require-hashes --no-deps \
    -c "$pins" -r requirements.lock
  .venv/bin/python -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
  echo "$want" > "$stamp"
fi
.venv/bin/python - "$pins" <<'PY' || { echo "setup: the environment is broken (see above)"; exit 1; }
import importlib.metadata as md, sys
import numpy, dolfinx, petsc4py, slepc4py, gmsh  # noqa: F401  (the compiled stack imports)
for line in open(sys.argv[1]):
    name, version = line.strip().split("==")
    dist = md.distribution(name)
    where = str(dist.locate_file(""))
    assert dist.version == version and where.startswith("/usr/"), \
        f"{name} {dist.version} from {where}: expected Debian's {version} under /usr"
PY
