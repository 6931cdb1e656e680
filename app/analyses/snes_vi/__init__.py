"""The MCP searches of the paper's Propositions 1-2 (eqs. (27)-(34)) with PETSc's SNES VI, for
MCEIP-mu and MCEIP-lambda^2: the bordered MCP (:mod:`.bordered`), the search over lifts
(:mod:`.search`) and the solutions with their evidence (:mod:`.results`). A search finds
solutions; it never proves that there are none."""
