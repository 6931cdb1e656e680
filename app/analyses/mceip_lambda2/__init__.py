"""MCEIP-lambda^2 (12)-(14) of one classified state: what the full-size pencil proves cheaply,
a proof of no solution on the exact slip-node reduction, else a search (SNES VI on the full
system, or on the reduction in the intervals of lambda^2 the proof set aside on large systems)."""
