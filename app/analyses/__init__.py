"""The analyses of one classified equilibrium state (paper sections 3-4): the reduced pencils
(10)-(16), the necessary condition (19) and sufficient condition (17)-(18), MCEIP-lambda^2
(12)-(14) and MCEIP-mu (21)-(23) by MCP search, enumeration and proof."""
