"""The environment is the locked one: every package of requirements.lock is installed at exactly
its locked version, and the compiled stack is Debian's (numpy 1.x from /usr, never a wheel)."""
from __future__ import annotations

import importlib.metadata as md
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
LOCK = ROOT / "requirements.lock"


def locked() -> dict[str, str]:
    """``{name: version}`` of requirements.lock (names normalised as in PEP 503)."""
    pins = re.findall(r"^([A-Za-z0-9_.\-]+)==([^\s\\;]+)", LOCK.read_text(encoding="utf-8"), re.M)
    return {re.sub(r"[-_.]+", "-", n).lower(): v for n, v in pins}


def installed(name: str) -> str | None:
    try:
        return md.version(name)
    except md.PackageNotFoundError:
        return None


def test_lock_pins_every_package_with_hashes():
    text = LOCK.read_text(encoding="utf-8")
    blocks = re.split(r"\n(?=[A-Za-z0-9])", text.split("\n", 3)[3])
    assert len(blocks) == len(locked()) > 20
    for block in blocks:
        assert "==" in block and "--hash=sha256:" in block, block.splitlines()[0]
    pins = locked()
    for debian in ("numpy", "scipy", "h5py", "pyyaml", "mpi4py"):   # apt's, not pip's
        assert debian not in pins, debian
    for direct in ("pydantic", "pyvista", "matplotlib", "pytest", "mkdocs", "uv", "python-flint"):
        assert direct in pins, direct


def test_installed_versions_are_the_locked_ones():
    wrong = {n: (v, installed(n)) for n, v in locked().items() if installed(n) != v}
    assert not wrong, f"installed differs from requirements.lock (run make setup): {wrong}"


def test_compiled_stack_is_debians():
    import numpy
    assert numpy.__version__.startswith("1."), numpy.__version__
    for name in ("numpy", "scipy", "mpi4py"):
        where = str(md.distribution(name).locate_file(""))
        assert where.startswith("/usr/lib/python3/"), (name, where)


@pytest.mark.parametrize("name", ["numpy", "petsc4py", "slepc4py", "dolfinx"])
def test_debian_module_imports_from_usr(name):
    mod = __import__(name)
    assert pathlib.Path(mod.__file__).resolve().is_relative_to("/usr"), mod.__file__
