"""MCEIP-lambda^2 (12)-(14) of one classified state: what the full-size pencil proves cheaply,
a proof of no solution on the exact slip-node reduction, else a search."""
