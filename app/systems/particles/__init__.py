"""``system.type: two_particles``: the paper's two-particle system (section 5, Fig. 1)."""
