"""Writing files so that nothing a user made is lost: whole or not at all."""

from __future__ import annotations

import hashlib
import os
import platform
import re
import secrets
import stat
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from microsim.errors import InputError

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
"""Formats of the matplotlib figures (``--plot``), by suffix."""
SCREENSHOT_SUFFIXES = (".png", ".jpg", ".jpeg")
"""Formats of the 3D views' screenshots (``--screenshot``), by suffix."""
TEMPORARY = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp$")
"""Names ``atomic_path`` gives its temporary files: ``.<name>.<pid>.<8 hex digits>.tmp``."""


def _writer_gone(pid: int) -> bool:
    """No process ``pid`` runs on this machine (so its temporary files are orphans)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False  # another user's live process
    return False


def remove_stale_temporaries(folder: str | Path, name: str | None = None) -> list[Path]:
    """Remove the temporary files of ``atomic_path`` whose writer is gone (killed during a
    write): of the target ``name`` in ``folder``, or of every target there.

    Parameters
    ----------
    folder : str or Path
    name : str or None
        The target file's name; None: every target.

    Returns
    -------
    list of Path
        The files removed.
    """
    removed = []
    for path in Path(folder).glob(".*.tmp"):
        match = TEMPORARY.match(path.name)
        if match is None or (name is not None and match["name"] != name):
            continue
        if _writer_gone(int(match["pid"])):
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def _existing_ancestor(folder: Path, flag: str, given: Path) -> Path | None:
    """The nearest of ``folder`` and its parents that exists; ``InputError`` naming
    ``flag`` and the user's ``given`` path when it is a file."""
    ancestor = next((p for p in (folder, *folder.parents) if p.exists()), None)
    if ancestor is not None and not ancestor.is_dir():
        where = "is a file" if ancestor == given else f"{ancestor} is a file"
        raise InputError(f"{flag} {given}: {where}, not a folder")
    return ancestor


def folder_possible(folder: str | Path, flag: str) -> None:
    """Check, without creating anything, that the output folder ``folder`` could be made
    and written: the nearest existing folder on its path takes new entries. For commands
    whose input takes long to check before ``writable_folder`` may create the folder (a
    bad input must leave nothing behind).

    Raises
    ------
    InputError
    """
    folder = Path(folder)
    ancestor = _existing_ancestor(folder, flag, folder)
    if ancestor is None or not os.access(ancestor, os.W_OK | os.X_OK) or (
            os.statvfs(ancestor).f_flag & os.ST_RDONLY):
        raise InputError(f"{flag} {folder}: cannot write in {ancestor}")


def _folder_ready(folder: Path, flag: str, given: Path) -> None:
    """Create ``folder`` if missing and write a probe file in it; ``InputError`` naming
    ``flag`` and the user's ``given`` path otherwise."""
    _existing_ancestor(folder, flag, given)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".microsim-probe.{os.getpid()}.{secrets.token_hex(4)}"
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        probe.unlink()
    except OSError as exc:
        raise InputError(f"{flag} {given}: cannot write in {folder}: "
                         f"{exc.strerror or exc}") from None


def writable_folder(folder: str | Path, flag: str) -> Path:
    """Create the output folder ``folder`` if missing and make sure files can be written
    in it, before any work is done (a check that fails after an hour of tracing loses
    the hour).

    Parameters
    ----------
    folder : str or Path
    flag : str
        The flag that named it, for the message (e.g. ``"--out"``).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        If it or a parent is a file, or it cannot be created or written in.
    """
    folder = Path(folder)
    _folder_ready(folder, flag, folder)
    return folder


FS_IOC_GETFLAGS = 0x80086601
"""Linux's ioctl reading a file's attributes (``lsattr``)."""
UNREPLACEABLE = {0x10: "immutable", 0x20: "append-only"}
"""Attributes (``chattr +i``, ``+a``) under which no one, root included, may rename a
file over another: FS_IMMUTABLE_FL and FS_APPEND_FL of linux/fs.h."""


def _attributes(path: Path) -> int:
    """The Linux attribute flags of the file ``path`` (0 where they cannot be read)."""
    import fcntl
    import struct

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except OSError:
        return 0
    try:
        return struct.unpack("i", fcntl.ioctl(fd, FS_IOC_GETFLAGS, struct.pack("i", 0)))[0]
    except OSError:
        return 0
    finally:
        os.close(fd)


def replaceable(path: str | Path, flag: str) -> None:
    """Check, before any work is done, that the finished output can be renamed over
    ``path`` (``atomic_path``'s last step): where ``path`` exists it must be a regular file
    (or a link, which is replaced, not followed) whose attributes allow replacing it, in a
    folder whose sticky bit, if set, lets this user replace it.

    Parameters
    ----------
    path : str or Path
    flag : str
        The flag that named it (or named its folder), for the message.

    Raises
    ------
    InputError
        If ``path`` is a folder, a device, a FIFO or a socket (a rename would put a file in
        its place), or cannot be replaced.
    """
    path = Path(path)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise InputError(f"{flag} {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{flag} {path}: is a folder, where a file is to be written; "
                         "move it away")
    if stat.S_ISLNK(st.st_mode):
        return
    if not stat.S_ISREG(st.st_mode):
        what = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket"
                if stat.S_ISSOCK(st.st_mode) else "a device")
        raise InputError(f"{flag} {path}: is {what}, not a file (the output would take "
                         "its place); give a file's path")
    locked = [name for bit, name in UNREPLACEABLE.items() if _attributes(path) & bit]
    if locked:
        raise InputError(f"{flag} {path}: the file is {locked[0]} (chattr +"
                         f"{locked[0][0]}), so it cannot be replaced; remove the attribute "
                         "or move it away")
    folder = os.stat(path.parent)
    uid = os.geteuid()
    if folder.st_mode & stat.S_ISVTX and uid not in (0, st.st_uid, folder.st_uid):
        raise InputError(f"{flag} {path}: belongs to another user in a folder with the "
                         "sticky bit, so it cannot be replaced; move it away")


def writable_file(path: str | Path, flag: str, suffixes: tuple[str, ...] = ()) -> Path:
    """Make sure the output file ``path`` can be written, before any work is done: its
    folder is created if missing and must take new files, and ``path`` is no folder and,
    where it exists, can be replaced (``replaceable``).

    Parameters
    ----------
    path : str or Path
    flag : str
        The flag that named it, for the message (e.g. ``"--output"``).
    suffixes : tuple of str
        Allowed suffixes, lower case (empty: any).

    Returns
    -------
    Path

    Raises
    ------
    InputError
    """
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{flag} {path}: must end in " + " or ".join(suffixes))
    if path.is_dir():
        raise InputError(f"{flag} {path}: is a folder; give a file name")
    _folder_ready(path.parent, flag, path)
    replaceable(path, flag)
    longest = _name_max(path.parent) - (len(os.fsencode(_temporary_name(""))))
    if len(os.fsencode(path.name)) > longest:
        raise InputError(f"{flag} {path.name[:40]}…: a file name of "
                         f"{len(os.fsencode(path.name))} bytes; this folder's file system "
                         f"takes at most {longest} here (the file is written under a "
                         "longer temporary name first)")
    return path


def _name_max(folder: Path) -> int:
    """The longest file name, in bytes, the file system of ``folder`` takes (255 where
    it does not say)."""
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _temporary_name(name: str) -> str:
    """The temporary file name ``atomic_path`` writes the file ``name`` under."""
    return f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` that replaces it when the block succeeds.

    The folder is created if missing. On any exception the temporary file is removed and
    an existing ``path`` is left untouched; on success ``os.replace`` renames it over
    ``path`` in one step (atomic on POSIX within a file system), so a crash never leaves a
    partial file under the final name. Temporary files of the same target that a killed
    writer left behind are removed first.

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
    remove_stale_temporaries(path.parent, path.name)
    tmp = path.parent / _temporary_name(path.name)
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


def write_section(path: str | Path, name: str, text: str,
                  heading: str | None = None) -> None:
    """Put ``text`` between the markers ``<!-- name: begin -->`` and ``<!-- name: end -->``
    of a text file (``replace_marked``; appended after ``heading`` where they are absent).
    """
    begin, end = f"<!-- {name}: begin -->", f"<!-- {name}: end -->"
    replace_marked(path, f"{begin}\n{text}\n{end}", begin, end, heading=heading)


def measured_with(script: str | Path, args: Sequence[str], load_before: float) -> str:
    """The sentence a section that a script measured opens with: ``Measured with `python
    scripts/NAME.py ARGS` on MACHINE, N CPUs, Python X.Y.Z, DATE; load average (1 min) A
    before, B after`` (B read now), without a closing full stop.

    Parameters
    ----------
    script : str or Path
        The script (its ``__file__``); only its name is written.
    args : sequence of str
        Its arguments as given (``sys.argv[1:]``, ``--write`` included).
    load_before : float
        The 1-minute load average when the measurement started (``os.getloadavg()[0]``).
    """
    command = " ".join(["python", f"scripts/{Path(script).name}", *args])
    return (f"Measured with `{command}` on {platform.machine()}, {os.cpu_count()} CPUs, "
            f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d')}; load average "
            f"(1 min) {load_before:.1f} before, {os.getloadavg()[0]:.1f} after")


def file_digest(path: str | Path) -> str:
    """SHA-256 of a file's bytes, hex: the provenance of an input (a mesh, a table one scale
    up)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
