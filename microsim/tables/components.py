"""Component names of a table: the total and the scattering orders.

A table simulated with ``orders = N`` holds ``"total"`` (all scattering orders) and
``"order1"``, …, ``"order{N-1}"`` and ``"order{N}+"`` (N or more scattering events), which
add up to the total. ``"single"`` is another name for ``"order1"``. Plain strings only, so
the command line can check a name without importing numpy.
"""

from __future__ import annotations

import re

ALIASES = {"single": "order1"}
"""Other names of components."""
_ORDER = re.compile(r"order([1-9][0-9]*)(\+?)")


def order_components(orders: int) -> tuple[str, ...]:
    """``("order1", …, "order{N-1}", "order{N}+")`` for ``orders`` = N ≥ 1."""
    if orders < 1:
        raise ValueError(f"orders must be >= 1, got {orders}")
    return tuple(f"order{k}" for k in range(1, orders)) + (f"order{orders}+",)


def components_for(orders: int) -> tuple[str, ...]:
    """The components of a table simulated with ``orders`` = N: ``"total"`` first, then
    ``order_components(N)``."""
    return ("total",) + order_components(orders)


def canonical_component(name: str) -> str:
    """The stored name of a component: ``"single"`` is ``"order1"``; ``"total"``,
    ``"order<k>"`` and ``"order<k>+"`` (k ≥ 1) are themselves.

    Raises
    ------
    ValueError
        For any other name.
    """
    name = ALIASES.get(name, name)
    if name != "total" and not _ORDER.fullmatch(name):
        raise ValueError(f"component must be total, single, order<k> or order<k>+ "
                         f"(k >= 1), got {name!r}")
    return name


def order_range(component: str) -> tuple[int, int | None]:
    """The scattering orders a component holds: (lowest, highest), None for no limit.

    ``"total"`` → (1, None); ``"single"`` and ``"order1"`` → (1, 1); ``"order3+"`` →
    (3, None).
    """
    name = canonical_component(component)
    if name == "total":
        return 1, None
    match = _ORDER.fullmatch(name)
    k = int(match.group(1))
    return k, None if match.group(2) else k
