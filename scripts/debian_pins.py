"""Print ``name==version`` for the compiled Python packages that come from Debian (apt).

scripts/setup.sh passes these as pip constraints and scripts/lock.sh as resolver constraints, so
that nothing installed into .venv replaces them: the compiled PETSc/DOLFINx modules break with
another numpy ("numpy.dtype size changed"). Run with Debian's interpreter (/usr/bin/python3).
"""
import importlib.metadata as md

# Debian's packages that the lock leaves out (scripts/lock.sh: --no-emit-package)
DEBIAN = ("numpy", "scipy", "h5py", "PyYAML", "mpi4py")

if __name__ == "__main__":
    for name in DEBIAN:
        try:
            print(f"{name}=={md.version(name)}")
        except md.PackageNotFoundError:
            pass
