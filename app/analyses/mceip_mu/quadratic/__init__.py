"""The quadratic MCEIP-mu of a curved obstacle (docs/method.md section 8): the problem and its
enumeration (:mod:`.problem`), the exact row structure of zero-reaction nodes (:mod:`.rows`), the
branch and bound (:mod:`.bb`), its trusted kernel and checker (:mod:`.check`) and the proof in
exact and ball arithmetic (:mod:`.proof`)."""
