"""What the commands share: the parser class, their flags and argument types, and how they
print results (aligned text for people, JSON for programs).

Usage errors are one ``error:`` line and exit status 2 (``Parser``); every flag's help text
gives its unit (angles in degrees). Imports nothing heavy: ``microsim --help`` loads it.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import re
import sys
from collections.abc import Callable, Iterator
from typing import Any, NoReturn

from microsim.errors import InputError
from microsim.surfaces.facts import SurfaceFacts


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one ``error:`` line and exit 2."""

    def error(self, message: str) -> NoReturn:
        """Print ``error: <prog>: <message>`` and exit with status 2."""
        raise InputError(f"{self.prog}: {message}")


def add_recipe_args(p: argparse.ArgumentParser) -> None:
    """Add the ``RECIPE`` argument and the repeatable ``--set section.key=value``."""
    p.add_argument("recipe", metavar="RECIPE", help="recipe file (TOML), see docs/recipes.md")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override a recipe value (repeatable), e.g. --set surface.alpha=0.3; "
                        "angles in degrees")


def add_json_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--json``: print machine-readable output instead of a table."""
    p.add_argument("--json", action="store_true", help="print JSON instead of text")


def add_direction_args(p: argparse.ArgumentParser) -> None:
    """Add the required ``--wi THETA,PHI`` and ``--wo THETA,PHI`` (degrees) of one
    direction pair."""
    pair = number_list(2, what="THETA,PHI in degrees")
    p.add_argument("--wi", type=pair, required=True, metavar="THETA,PHI",
                   help="incident direction, degrees")
    p.add_argument("--wo", type=pair, required=True, metavar="THETA,PHI",
                   help="outgoing direction, degrees")


def add_seed_arg(p: argparse.ArgumentParser, what: str) -> None:
    """Add ``--seed N`` overriding the recipe's seed of ``what``."""
    p.add_argument("--seed", type=nonnegative_int, default=None,
                   help=f"override the recipe's {what} seed (integer >= 0)")


def add_realisations_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--realisations K`` overriding ``simulation.realisations``."""
    p.add_argument("--realisations", type=positive_int, default=None, metavar="K",
                   help="independent surface realisations to average (overrides "
                        "simulation.realisations; default: the generator's, 1 for "
                        "deterministic geometry)")


def error_model_note(model: str, realisations: int, what: str = "z-scores") -> str:
    """One line saying what a result's errors include (``rays``, ``ensemble``, ...) and so
    what ``what`` (the numbers made from them) are about."""
    if model == "ensemble":
        return (f"errors: ensemble of {realisations} surface realisations (they include the "
                f"spread between tiles, so {what} are about the surface)")
    if model == "rays":
        return (f"errors: rays only, one tile ({what} are conditional on this tile, not "
                "on the surface its recipe names)")
    return f"errors: {model}"


def add_threads_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--threads N`` for the commands that trace."""
    p.add_argument("--threads", type=positive_int, default=None,
                   help="tracing threads (default: every CPU; results do not depend on it)")


def add_memory_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--memory-limit GIB``."""
    gib = number_list(1, low=0.0, low_open=True, what="a positive number of GiB")
    p.add_argument("--memory-limit", type=lambda t: gib(t)[0], default=None, metavar="GIB",
                   help="refuse work (a tile, ray paths, an export grid, a Monte Carlo "
                        "model's walks, a fit) estimated to need more memory than this many "
                        "GiB (default: $MICROSIM_MEMORY_LIMIT or 2)")


def add_component_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--component C``: which of a table's components a command reads."""
    p.add_argument("--component", type=component_name, default="total", metavar="C",
                   help="the table's component: total (all scattering orders, default), "
                        "single or order1 (single scattering), order<k> (k scattering "
                        "events) or order<k>+ (k or more), as the table holds them "
                        "(docs/table-format.md)")


def component_name(text: str) -> str:
    """argparse type: a component name (``microsim.tables.components``)."""
    from microsim.tables.components import canonical_component

    try:
        canonical_component(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not total, single, order<k> or "
                                         "order<k>+ (k >= 1)") from None
    return text


def table_component(table: Any, name: str, path: Any) -> str:
    """The stored name of ``--component name`` in a table read from ``path``.

    Raises
    ------
    InputError
        If the table does not hold that component.
    """
    try:
        return table.component(name)
    except ValueError:
        raise InputError(f"--component {name}: {path} holds "
                         + ", ".join(table.components)) from None


def channels_json(table: Any) -> dict[str, Any]:
    """What a command's JSON adds about a table's channels: nothing for an RGB table (its
    per-channel lists are R, G, B), ``channels`` (``Channels.names``: ``400nm``, …) and
    ``wavelengths`` (nm) for a spectral one, naming the entries of every per-channel
    list."""
    channels = table.channels
    if not channels.spectral:
        return {}
    return {"channels": list(channels.names), "wavelengths": list(channels.wavelengths)}


def channel_mean(values: Any) -> float:
    """A per-channel quantity as the one number text reports give: the mean over the
    channels (R, G, B, or the wavelengths)."""
    values = list(values)
    return sum(values) / len(values)


def channels_words(table: Any) -> str:
    """The channels a text report's means are over: ``R, G and B`` or ``the 16
    wavelengths (400-700 nm)``."""
    return wavelengths_words(table.channels.wavelengths)


def wavelengths_words(nm: Any) -> str:
    """``channels_words`` of a table's wavelengths (None: RGB)."""
    if nm is None:
        return "R, G and B"
    if len(nm) == 1:
        return f"the one wavelength ({nm[0]:g} nm)"
    return f"the {len(nm)} wavelengths ({nm[0]:g}-{nm[-1]:g} nm)"


def flag_overrides(args: argparse.Namespace, section: str, *flags: str) -> list[str]:
    """``--set`` strings ``section.<flag>=<value>`` for each of ``flags`` that was given
    (argparse destinations named as the section's recipe keys, e.g. ``--seed N`` gives
    ``section.seed=N``), so the schema validates a flag as it validates ``--set``."""
    return [f"{section}.{flag}={getattr(args, flag)!r}" for flag in flags
            if getattr(args, flag) is not None]


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer >= 0") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer >= 0")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (plain digits or scientific like 1e6)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 1 or not value.is_integer():
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer >= 1")
    return int(value)


def bounded_int(low: int, high: int, why: str) -> Any:
    """argparse type: an integer (plain digits or scientific like 1e3) from ``low`` to
    ``high``; ``why`` says where the upper bound comes from."""
    def parse(text: str) -> int:
        try:
            value = float(text) if not text.strip().lstrip("+").isdigit() else int(text)
        except ValueError:
            value = math.nan
        if not (low <= value <= high and float(value).is_integer()):  # NaN: neither
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer from {low} to "
                                             f"{high} ({why})")
        return int(value)
    return parse


def finite_float(text: str) -> float:
    """argparse type: a finite number."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def number_list(count: int | None = None, low: float = -math.inf, high: float = math.inf,
                low_open: bool = False, what: str = "numbers") -> Any:
    """argparse type: comma-separated finite numbers, ``count`` of them (None: one or
    more), each in [low, high] (or (low, high] with ``low_open``).

    Parameters
    ----------
    count : int or None
    low, high : float
    low_open : bool
    what : str
        How the error names the expected value, e.g. ``"THETA,PHI in degrees"``.

    Returns
    -------
    callable
        ``str -> list[float]``.
    """

    def parse(text: str) -> list[float]:
        try:
            values = [float(t) for t in text.split(",") if t.strip()]
        except ValueError:
            values = []
        ok = bool(values) and (count is None or len(values) == count) and all(
            math.isfinite(v) and (low < v if low_open else low <= v) and v <= high
            for v in values)
        if not ok:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}")
        return values

    return parse


LIST_SHOWN = 8
"""Text output shows lists up to this long whole, longer ones by their ends and length."""


def number_text(x: float, spec: str, scale: float = 1.0, suffix: str = "") -> str:
    """``scale * x`` formatted with ``spec`` and followed by ``suffix``, or ``n/a`` as wide
    where ``x`` is undefined (NaN or infinite: no light in a bin, no spread between
    tiles), so a text report never prints nan; e.g. ``number_text(0.1234, "7.2f", 100,
    "%")`` is ``"  12.34%"``.

    Parameters
    ----------
    x : float
    spec : str
        A format specification (``"7.2f"``, ``"+.1f"``); its width pads ``n/a``.
    scale : float
        What ``x`` is shown times (100 for a percentage).
    suffix : str
        The unit after the number (``"%"``).
    """
    if math.isfinite(x):
        return format(scale * x, spec) + suffix
    width = re.match(r"[<>=^]?[+\- ]?0?(\d*)", spec).group(1)
    return "n/a".rjust(int(width or 0) + len(suffix))


def readable(value: Any, digits: int = 4) -> str:
    """A value for text output: numbers to ``digits`` significant figures, lists and
    dicts item by item (long lists by their ends and length). JSON keeps full precision.

    Parameters
    ----------
    value : Any
        A number, string, bool, None, or a list / tuple / dict of them.
    digits : int
        Significant figures of floats.

    Returns
    -------
    str
    """
    if isinstance(value, float):
        return number_text(value, f".{digits}g")
    if isinstance(value, list | tuple):
        items = [readable(v, digits) for v in value]
        if len(items) > LIST_SHOWN:
            items = items[:3] + ["…"] + items[-1:]
            return f"[{', '.join(items)}] ({len(value)} values)"
        return f"[{', '.join(items)}]"
    if isinstance(value, dict):
        return ", ".join(f"{k} {readable(v, digits)}" for k, v in value.items())
    return str(value)


def with_error(value: float, error: float) -> str:
    """``value ± error`` with the error to 2 significant figures and the value to the
    same decimal place (the digits that mean something), e.g. ``0.2912 ± 0.0012``."""
    if not (math.isfinite(value) and math.isfinite(error) and error > 0):
        return f"{number_text(value, '.5g')} ± {number_text(error, '.2g')}"
    places = 1 - math.floor(math.log10(error))
    if places <= 0:
        return f"{round(value, places):.0f} ± {round(error, places):.0f}"
    return f"{value:.{places}f} ± {error:.{places}f}"


def roughness_text(facts: SurfaceFacts) -> str:
    """``alpha realised R (target T)`` of a surface's facts, without a target where the
    surface has none (an imported mesh); pooled over several realisations,
    ``alpha realised R ± E over K tiles (...)``; ``""`` when no roughness is reported."""
    if facts.alpha_realised is None:
        return ""
    target = facts.tile.alpha_target
    error = facts.alpha_realised_stderr
    pooled = "" if error is None else (
        f" ± {readable(error.to_json())} over {facts.realisations} tiles")
    text = f"alpha realised {readable(facts.alpha_realised.to_json())}{pooled} (from facet slopes"
    return text + ("" if target is None else f"; target {readable(target.to_json())}") + ")"


def print_json(data: Any) -> None:
    """Print ``data`` as JSON (NaN becomes null, so the output is strict JSON)."""

    def clean(x: Any) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, list | tuple):
            return [clean(v) for v in x]
        if hasattr(x, "tolist"):
            return clean(x.tolist())
        return x

    print(json.dumps(clean(data), indent=2))


def progress_display() -> Any:
    """A rich progress display on stderr whose bars show their description, the share
    done, the time elapsed and the time remaining at the rate so far (``rich.progress``:
    use it as a context manager, add a task per bar)."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                    TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                    console=Console(stderr=True))


@contextlib.contextmanager
def progress_steps(label: str, json_output: bool) -> Iterator[Callable[[int, int], None] | None]:
    """One bar labelled ``label`` on a terminal (``progress_display``) and its callback
    ``show(done, total)``; None when stderr is not a terminal or the command prints JSON,
    so that pipes and logs get no progress lines."""
    if json_output or not sys.stderr.isatty():
        yield None
        return
    with progress_display() as bar:
        task = bar.add_task(label, total=None)
        yield lambda done, total: bar.update(task, completed=done, total=total)
