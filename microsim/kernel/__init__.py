"""The compiled transport kernel: everything a path does between two Embree queries.

The modules of this package are compiled with numba (``nogil=True``), so the tracer's worker
threads run them side by side with Embree's queries: ``rng`` (counter-based random numbers),
``scatter`` (facet scattering events), ``transport`` (one step of every live path after a
query: hit point, media, scattering, side wrap, escape records and compaction) and
``tally`` (escape records into bin sums). ``microsim.trace`` drives them.

Compiled code is cached on disk in a folder under the user's cache directory named by a
digest of this package's sources and the numba version (``cache_dir``): numba's own cache
notices edits only in the file of the function it compiles, not in the functions it calls
from other files, and the package folder may be read-only. ``MICROSIM_CACHE_DIR`` moves it.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numba


def cache_dir() -> Path:
    """Folder of the compiled kernel: ``$MICROSIM_CACHE_DIR``, else ``$XDG_CACHE_HOME`` or
    ``~/.cache``, then ``microsim/numba-<digest>`` (a temporary folder if none is writable)."""
    digest = hashlib.sha256(numba.__version__.encode())
    for source in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(source.read_bytes())
    root = os.environ.get("MICROSIM_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "microsim")
    folder = Path(root) / f"numba-{digest.hexdigest()[:16]}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        folder = Path(tempfile.gettempdir()) / "microsim" / folder.name
        folder.mkdir(parents=True, exist_ok=True)
    return folder


numba.config.CACHE_DIR = str(cache_dir())
