"""Does the predicted divergence happen? Nonsmooth dynamics from an equilibrium state (issue 37).

:func:`app.analyses.transient.simulate` integrates ``M u'' + K u = f + B^T r`` from a state of
the loading path with its applied loads held, Signorini contact and Coulomb friction at the
contact nodes solved exactly at every step (``engine.py``), started on the state's divergence
mode (``mode.py``, rebuilt from MCEIP-lambda^2's ``lambda^2`` and slip pattern), and measures
the growth rate of the mode's amplitude against ``lambda = sqrt(lambda^2)``
(docs/validation.md, "Does the predicted divergence happen?"). So far a Python API on dense
matrices, checked in tests/test_transient.py; not yet an analysis of a scene.
"""
from app.analyses.transient.engine import Transient, simulate  # noqa: F401
from app.analyses.transient.mode import DivergenceMode, divergence_mode  # noqa: F401
