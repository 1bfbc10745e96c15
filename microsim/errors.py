"""Errors that the command line turns into exit statuses.

``InputError`` is bad input from the user (a recipe key, a flag, a file): the CLI prints
one line ``error: <message>`` on stderr and exits with status 2; an ``InputWarning`` is
one line ``warning: <message>`` and the command goes on. Anything else that escapes is
an internal failure (exit status 1).
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input; the message names the key or flag and what is allowed.

    Parameters
    ----------
    message : str
        One line, e.g. ``"surface.alpha = -1: must be > 0"``.
    """


class InputWarning(UserWarning):
    """Something about the user's input they should know, that does not stop the command
    (e.g. a damaged part of a table that is not needed); the CLI prints it as one line
    ``warning: <message>`` on stderr."""
