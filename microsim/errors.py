"""Errors that the command line turns into exit statuses.

``InputError`` is bad input from the user (a recipe key, a flag, a file): the CLI prints
one line ``error: <message>`` on stderr and exits with status 2. Anything else that
escapes is an internal failure (exit status 1).
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input; the message names the key or flag and what is allowed.

    Parameters
    ----------
    message : str
        One line, e.g. ``"surface.alpha = -1: must be > 0"``.
    """
