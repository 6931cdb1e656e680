"""The pictures of a study, drawn from the results alone and never recomputing: plots
(matplotlib), off-screen screenshots of the body (pyvista) and ``python -m app render``."""
