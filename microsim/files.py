"""Writing files so that nothing a user made is lost: whole or not at all."""

from __future__ import annotations

import hashlib
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` that replaces it when the block succeeds.

    The folder is created if missing. On any exception the temporary file is removed and
    an existing ``path`` is left untouched; on success ``os.replace`` renames it over
    ``path`` in one step (atomic on POSIX within a file system), so a crash never leaves a
    partial file under the final name.

    Parameters
    ----------
    path : str or Path
        The final file.

    Yields
    ------
    Path
        Where to write.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    # created like any new file (0666 less the umask), unlike mkstemp's private 0600
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def replace_marked(path: str | Path, block: str, begin: str, end: str,
                   heading: str | None = None) -> None:
    """Put ``block`` in place of the part of a text file from ``begin`` to ``end``.

    Benchmark scripts keep their figures in docs this way: the rest of the page is kept.

    Parameters
    ----------
    path : str or Path
        The text file (UTF-8), rewritten atomically.
    block : str
        The new part, itself starting with ``begin`` and ending with ``end``.
    begin, end : str
        The markers (e.g. HTML comments in Markdown).
    heading : str or None
        Where the file has no ``begin`` yet, the block is appended, after this heading
        line when given.
    """
    path = Path(path)
    page = path.read_text(encoding="utf-8")
    if begin in page:
        head, rest = page.split(begin, 1)
        page = head + block + rest.split(end, 1)[1]
    else:
        intro = f"{heading}\n\n" if heading else ""
        page = f"{page.rstrip()}\n\n{intro}{block}\n"
    with atomic_path(path) as tmp:
        tmp.write_text(page, encoding="utf-8")


def file_digest(path: str | Path) -> str:
    """SHA-256 of a file's bytes, hex: the provenance of an input (a mesh, a table one scale
    up)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
