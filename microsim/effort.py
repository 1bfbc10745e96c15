"""A quick look at any command: ``$MICROSIM_EFFORT``, the fraction of the work to do.

Unset (or 1), every command does what its recipe and flags ask. ``MICROSIM_EFFORT=F`` with
0 < F < 1 makes each simulation trace F of the rays (``simulation.rays``, ``--rays``,
``max_rays``), average F of the realisations (at least 2 where the recipe has 2 or more, so
the errors keep their ensemble model) and each render take F of its samples per pixel, all
rounded up. The commands print one ``warning:`` line saying so, and tables record the rays
and realisations they used (docs/goniometer.md, "A quick look"). The documentation's
commands run so in the tests (tests/test_docs_run.py). Pure Python, imports nothing heavy.
"""

from __future__ import annotations

import dataclasses
import math
import os

from microsim.errors import InputError
from microsim.settings import Simulation

EFFORT_ENV = "MICROSIM_EFFORT"


def effort() -> float:
    """The fraction of the work to do: ``$MICROSIM_EFFORT``, 1 when unset.

    Raises
    ------
    InputError
        If it is not a number in (0, 1].
    """
    text = os.environ.get(EFFORT_ENV)
    if text is None or not text.strip():
        return 1.0
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value <= 1:
        raise InputError(f"${EFFORT_ENV} = {text!r}: must be a number in (0, 1], the "
                         "fraction of the rays, realisations and samples per pixel to use")
    return value


def note() -> str | None:
    """The ``warning:`` text of a reduced effort, or None at full effort."""
    f = effort()
    if f == 1:
        return None
    return (f"${EFFORT_ENV} = {f:g}: {100 * f:g}% of the rays, realisations and samples per "
            "pixel asked for (a quick look; unset it for the real numbers)")


def scaled(count: int, least: int = 1) -> int:
    """``count`` times the effort, rounded up, at least ``min(count, least)``."""
    f = effort()
    if f == 1:
        return count
    return max(min(count, least), math.ceil(f * count))


def scaled_simulation(sim: Simulation, rays_per_realisation: int) -> Simulation:
    """A resolved ``[simulation]`` section at the effort: its rays, realisations and
    adaptive bounds scaled (``scaled``), every constraint the recipe parser checks kept
    (``rays_per_realisation`` rays or more per realisation, the bounds at or above the
    start)."""
    if effort() == 1:
        return sim
    k = scaled(sim.realisations_or_one, least=2)
    rays = max(scaled(int(sim.rays)), rays_per_realisation * k)
    changes: dict[str, int] = {"rays": rays}
    if sim.realisations is not None:
        changes["realisations"] = k
    if sim.max_rays is not None:
        changes["max_rays"] = max(scaled(int(sim.max_rays)), rays)
    if sim.max_realisations is not None:
        changes["max_realisations"] = max(scaled(int(sim.max_realisations), least=2), k)
    return dataclasses.replace(sim, **changes)
