"""How the process takes memory from the system: base pages, and what it frees kept.

The first touch of a page costs the operating system a fault and a page of zeros, and on
a virtual machine that hands memory it does not use back to its host (free page
reporting, a balloon) the host must back the page again first. On the 2-core machine of
docs/performance.md a GiB touched for the first time cost 0.35 s in 4 KiB pages and 9 s in
the 2 MiB pages numpy asks for on large arrays (``madvise(MADV_HUGEPAGE)``, with the
kernel's transparent huge pages in ``madvise`` mode). A run allocates and frees its large
per-batch arrays (outcomes, tallies, principal components) hundreds of times; each one
returned to the system in between is such a first touch again. ``keep_pages`` asks numpy
for base pages and glibc's allocator to keep what the process frees (``mallopt``: blocks
up to ``MMAP_LIMIT`` from its heaps, which it returns to the system only beyond
``TRIM_LIMIT`` free at their top), so a run touches each page of its peak once: a
32-wavelength table's system time 9.3–9.7 → 1.7–2.0 s, its own wall time 14.8–15.3 →
9.7–10.3 s (docs/performance.md, "Spectral tables against RGB").

The price is that a process's resident memory stays near its peak after a run, which a
command, whose process ends with it, does not notice. Elsewhere (musl, macOS, Windows)
only numpy's part applies.
"""

from __future__ import annotations

import ctypes

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
"""glibc's ``mallopt`` parameters (malloc.h)."""
MMAP_LIMIT = 32 << 20
"""Largest block glibc takes from its heaps rather than a mapping of its own, which it
would unmap when freed: glibc's own ceiling on 64-bit systems (32 MiB; it refuses more),
above the largest per-batch array of a shipped recipe (a beam's 32-wavelength outcomes:
31 MB)."""
TRIM_LIMIT = (1 << 31) - 1
"""Free memory at the top of a heap that glibc returns to the system (the largest value
``mallopt`` takes, 2 GiB)."""
_KEPT = False


def keep_pages() -> None:
    """Have numpy use base pages and glibc keep what the process frees (once per
    process; later calls do nothing)."""
    global _KEPT
    if _KEPT:
        return
    try:  # numpy's switch of the NUMPY_MADVISE_HUGEPAGE variable, read at its import
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:
        _set_madvise_hugepage = None
    if _set_madvise_hugepage is not None:
        _set_madvise_hugepage(False)
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError, TypeError):  # not glibc (no mallopt, no C library)
        mallopt = None
    if mallopt is not None:
        mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
        mallopt(M_MMAP_THRESHOLD, MMAP_LIMIT)
        mallopt(M_TRIM_THRESHOLD, TRIM_LIMIT)
    _KEPT = True
