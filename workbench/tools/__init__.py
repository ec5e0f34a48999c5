"""The tools that run experiments or read their recordings as a whole, above the Python API:
``info`` and ``replay`` (:mod:`.provenance`), ``compare`` (:mod:`.compare`), ``screenshot`` in a
real browser (:mod:`.browser`), ``view``; their command-line layer is :mod:`.commands`. The
drawing primitives they stand on are :mod:`workbench.recording`'s."""
