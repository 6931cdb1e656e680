"""``system.type: gmsh``: a 2D elastic body from a user's Gmsh file, read in a limited child
process: schema, checks of the files, mesh, operators, loading program and fields."""
