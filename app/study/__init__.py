"""Studies end to end: the driver behind ``python -m app run``, one loading study, parameter sweeps
(an MPI task farm) and mesh-refinement studies with their report."""
