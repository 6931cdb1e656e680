"""Loading paths: quasi-static increments of Signorini contact with Coulomb friction against a flat
or curved rigid obstacle, loading programs, the contact flexibility W = B K^-1 B^T, the
classification of the contact nodes and the physical sanity of a path."""
