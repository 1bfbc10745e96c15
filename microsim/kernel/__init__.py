"""The compiled transport kernel: everything a path does between two Embree queries.

The modules of this package are compiled with numba (``nogil=True``), so the tracer's worker
threads run them side by side with Embree's queries: ``rng`` (counter-based random numbers),
``events`` (the facet materials' scattering events, ``microsim.materials``, behind one
dispatch), ``transport`` (one step of every live path after a query: hit point, media,
scattering, side wrap, escape records and compaction; ``slots`` lays out a path's state)
and ``tally`` (escape records into bin sums). ``packing`` and ``tabulated`` pack a tile's
materials into the arrays the kernel reads. ``microsim.measurement.scene`` drives them.

Compiled code is cached on disk (``microsim.jit``).
"""
