"""The message of an error a call raises, for tests that compare whole messages."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest


def refused(error: type[Exception], call: Callable[..., Any], *args: Any,
            **kwargs: Any) -> str:
    """The message of the ``error`` (an exception of that class or a subclass) that
    ``call(*args, **kwargs)`` raises; the test fails if it raises none."""
    with pytest.raises(error) as caught:
        call(*args, **kwargs)
    return str(caught.value)
