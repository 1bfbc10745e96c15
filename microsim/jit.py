"""Compiled code: numba's options, and where its compiled functions are cached.

Compiled code is cached on disk in a folder under the user's cache directory named by a
digest of the sources of every file that holds compiled code (``COMPILED``) and of the
numba version: numba's own cache notices edits only in the file of the function it
compiles, not in the functions it calls from other files (the transport kernel calls the
material kinds' events), and the package folder may be read-only. ``MICROSIM_CACHE_DIR``
moves it. Every module with compiled code imports this one before it defines any.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numba

PACKAGE = Path(__file__).parent
COMPILED = ("jit.py", "kernel", "materials", "analytic/velvet.py", "surfaces/faces.py",
            "tables/accumulate.py")
"""The folders (every ``.py`` file in them) and files of ``microsim`` that hold compiled
code or kernel language (``microsim.materials.base.kernel``), and this file (the options)."""
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
"""Compilation options of every kernel function: cached on disk, without the GIL, IEEE
floating-point semantics (a division by zero gives inf, not an exception)."""
INLINE = {**JIT, "inline": "always"}
"""The same, inlined into the caller (small functions on the per-segment path)."""


def compiled_sources() -> list[Path]:
    """The source files ``COMPILED`` names, sorted."""
    files: list[Path] = []
    for name in COMPILED:
        path = PACKAGE / name
        files += sorted(path.glob("*.py")) if path.is_dir() else [path]
    return sorted(files)


def cache_dir() -> Path:
    """Folder of the compiled code: ``$MICROSIM_CACHE_DIR``, else ``$XDG_CACHE_HOME`` or
    ``~/.cache``, then ``microsim/numba-<digest>`` (a temporary folder if none is writable)."""
    digest = hashlib.sha256(numba.__version__.encode())
    for source in compiled_sources():
        digest.update(source.relative_to(PACKAGE).as_posix().encode())
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
