"""``system.type: block``: the elastic block of Villechaise and Zeghloul on a flat rigid obstacle
(docs/method.md section 5): schema, mesh, operators, loading path and fields."""
