"""Library warnings inside a study are caught and explained (app/common/library_warnings.py), never raw.

- a numpy overflow in an app function is recorded with that function, counted once per kind,
  logged as a WARNING when unknown and at INFO when known (the det overflow of the dense
  MCEIP-mu Newton step), and nothing escapes even when warnings are errors outside;
- the default study raises no library warning at all (under RuntimeWarning-as-error).
"""
from __future__ import annotations

import logging
import warnings

import numpy as np
import yaml
from mpi4py import MPI

from app.common.library_warnings import explained, merged


def _overflow_twice():
    big = np.array([1e308])
    return big * 10.0, big * 10.0


def test_unknown_warning_is_named_by_its_app_function(caplog):
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # nothing may escape the block
        with caplog.at_level(logging.INFO, logger="app.common.library_warnings"), explained() as rec:
            _overflow_twice()
            _overflow_twice()
    (r,) = rec.as_list()
    assert r["category"] == "RuntimeWarning" and "overflow" in r["message"]
    assert r["where"].endswith("(_overflow_twice)") and "test_library_warnings.py:" in r["where"]
    assert r["count"] == 4 and r["explanation"] is None
    logged = [x for x in caplog.records if x.name == "app.common.library_warnings"]
    assert len(logged) == 1 and logged[0].levelno == logging.WARNING      # once, when first seen
    assert "_overflow_twice" in logged[0].getMessage() and "please report" in logged[0].getMessage()


def test_singular_newton_steps_raise_no_warning():
    """A stack of Jacobians whose determinants overflow the double range (1e3^150), one of them
    singular: the singular one gets the least-squares step, the others the solve, and no library
    warning is raised (the test uses slogdet's sign, not det)."""
    from app.analyses.mceip_mu import candidates
    J = np.stack([1e3 * np.eye(150), np.eye(150)])
    J[1, 5, :] = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with explained() as rec:
            d = candidates._newton_steps(J, np.ones((2, 150)))
    assert rec.as_list() == []
    assert np.allclose(d[0], 1e-3)                       # the ordinary solve
    assert np.all(np.isfinite(d[1])) and d[1][5] == 0.0   # minimum-norm step: the zero row's unknown untouched


def test_merged_sums_counts_over_ranks():
    a = {"category": "RuntimeWarning", "message": "m", "where": "w", "count": 2, "explanation": None}
    b = dict(a, count=3)
    c = dict(a, message="other", count=1)
    assert [(r["message"], r["count"]) for r in merged([[a], [b, c]])] == [("m", 5), ("other", 1)]


def test_default_study_raises_no_library_warning():
    from app.scene.schema import default_scene_path, parse_scene
    from app.study.run import study
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = study(parse_scene(data), MPI.COMM_WORLD).to_dict()
    assert "library_warnings" not in res, res.get("library_warnings")
    assert res["warnings"] == []


def test_a_cold_jit_cache_records_no_warning(tmp_path):
    """On an empty JIT cache (a fresh machine) ffcx leaves each new C file's placeholder open,
    which Python reports as a ResourceWarning from ffcx/codegeneration/jit.py when it closes it.
    That warning says nothing about the computation (IGNORED_IN_LIBRARY): it is not recorded, so
    it reaches neither results.json nor a user beside a one-line error."""
    import dolfinx
    import ufl

    from app.systems.jit import JIT_PARAMS
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    V = dolfinx.fem.FunctionSpace(mesh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    cold = dict(JIT_PARAMS, cache_dir=str(tmp_path / "fenics"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # nothing may escape the block
        with explained() as rec:
            dolfinx.fem.form(u * v * ufl.dx, jit_params=cold)
    assert any((tmp_path / "fenics").glob("*.c")), "the form was not compiled into the cold cache"
    assert rec.as_list() == []


def test_a_file_left_unclosed_by_any_library_is_not_recorded():
    """A Ctrl-C's KeyboardInterrupt landing inside threadpoolctl's reading of /proc/self/maps left
    that file unclosed, and the ResourceWarning Python gave for it was reported as an unknown
    library warning beside the run's one interrupt line. Files a library leaves unclosed are file
    hygiene, whichever library: not recorded; other warnings of that library still are."""
    lib = "/usr/lib/python3/dist-packages/threadpoolctl.py"
    with explained() as rec:
        warnings.warn_explicit("unclosed file <_io.BufferedReader name='/proc/self/maps'>", ResourceWarning, lib, 1566)
        warnings.warn_explicit("overflow encountered", RuntimeWarning, lib, 10)
    assert [r["category"] for r in rec.as_list()] == ["RuntimeWarning"]
