"""The memory guard: work estimated to need more memory than the budget is refused
before it starts, with the estimate, the budget and how to raise it.

The budget is ``--memory-limit GIB`` where a command has it, else the environment
variable ``MICROSIM_MEMORY_LIMIT`` (GiB), else 2 GiB. The command line hands a command's
flag to every guard it reaches (``flag_limit``). Pure Python, imports nothing heavy.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from microsim.errors import InputError

DEFAULT_LIMIT_GIB = 2.0
LIMIT_ENV = "MICROSIM_MEMORY_LIMIT"


def memory_limit(flag: float | None = None) -> float:
    """The memory budget in GiB: the ``--memory-limit`` flag, else $MICROSIM_MEMORY_LIMIT,
    else 2."""
    if flag is not None:
        return flag
    text = os.environ.get(LIMIT_ENV)
    if text is None:
        return DEFAULT_LIMIT_GIB
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise InputError(f"${LIMIT_ENV} = {text!r}: must be a positive number of GiB")
    return value


def check_memory(need_bytes: float, what: str, remedy: str,
                 limit_gib: float | None = None) -> None:
    """Refuse work whose estimated memory exceeds the budget.

    Parameters
    ----------
    need_bytes : float
        The estimate (may be huge or infinite for absurd parameters).
    what : str
        What needs it, starting the message, e.g. ``"surface: this tile"``.
    remedy : str
        How to need less, e.g. ``"lower the resolution"``.
    limit_gib : float or None
        The ``--memory-limit`` flag, if given.

    Raises
    ------
    InputError
        Naming the estimate (3 significant figures), the budget and how to raise it.
    """
    limit = memory_limit(limit_gib)
    if need_bytes > limit * 2**30:
        raise InputError(f"{what} needs about {need_bytes / 2**30:.3g} GiB (estimated), over "
                         f"the {limit:g} GiB limit; {remedy}, or raise the limit with "
                         f"--memory-limit GIB or ${LIMIT_ENV}")


@contextlib.contextmanager
def flag_limit(limit_gib: float | None) -> Iterator[None]:
    """A command's ``--memory-limit`` for everything the block runs: while it runs,
    ``$MICROSIM_MEMORY_LIMIT`` holds the flag, so the guards the command does not hand it
    to (a Monte Carlo model's walks, a fit's residuals) and the processes it starts (the
    workers of a local Dask cluster, which inherit the environment) use it too. Nothing
    changes when ``limit_gib`` is None."""
    before = os.environ.get(LIMIT_ENV)
    if limit_gib is not None:
        os.environ[LIMIT_ENV] = repr(limit_gib)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(LIMIT_ENV, None)
        else:
            os.environ[LIMIT_ENV] = before
