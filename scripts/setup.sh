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
      bubblewrap                                      # the sandbox of a user's Gmsh files (app/systems/gmsh_sandbox.py)
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

# Pin numpy (and the other compiled Debian packages) to Debian's versions: the compiled
# PETSc/DOLFINx modules break with numpy 2 ("numpy.dtype size changed").
pins=.venv/debian-pins.txt
"$py" - > "$pins" <<'PY'
import importlib.metadata as md
for name in ("numpy", "scipy", "h5py", "PyYAML", "mpi4py"):
    try:
        print(f"{name}=={md.version(name)}")
    except md.PackageNotFoundError:
        pass
PY
stamp=.venv/.setup-stamp
want="$(cat pyproject.toml constraints.txt "$pins" | sha256sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing Python packages into .venv"
  .venv/bin/python -m pip install -q --disable-pip-version-check \
    -c constraints.txt -c "$pins" -e ".[test]"
  echo "$want" > "$stamp"
fi
.venv/bin/python -c 'import numpy, dolfinx, petsc4py, slepc4py, gmsh; assert numpy.__version__.startswith("1.")' \
  || { echo "setup: the environment is broken (numpy/petsc4py/dolfinx do not import)"; exit 1; }
