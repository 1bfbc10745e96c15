"""Property-based fuzzing of the command line: recipe values, flags and output paths.

Whatever the input, a command exits 0 or 2 and never with a traceback (the commands run
in-process, so any exception fails the test with its traceback); an exit 2 prints exactly
one ``error:`` line; a table that was written holds no NaN (an error is NaN only where its
bin is empty, as docs/table-format.md says).

Kept fast (about 15 s for the three tests): small work is forced (a memory budget of
0.1 GiB for tiles, tables and rays, at most 300 rays per incident direction unless the
rays are the flag under test, and then only small or invalid counts); the two broad tests
run ``EXAMPLES`` = 100 examples each and the one over accepted values, where tables get
written, ``ACCEPTED_EXAMPLES`` = 40; hypothesis draws them from a fixed seed
(``derandomize``) so CI sees the same inputs every run. The deadline per example is 60 s:
generous, because the machine is shared and timings are noisy; it is there to catch a
hang, not to time. (Raising the counts and turning ``derandomize`` off is how to search
deeper by hand: 3 × 800 random examples of the broad tests and 1500 of the accepted
values passed when this was written.)
"""

from __future__ import annotations

import json
import math
import tempfile
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from microsim.recipe import MATERIAL_KINDS, SIMULATION, TABLE
from microsim.schema import Key
from microsim.surfaces import SURFACES

ROOT = Path(__file__).resolve().parent.parent
RECIPES = {"gaussian-0.3.toml": "gaussian", "vgroove-30.toml": "vgroove",
           "cylinders.toml": "cylinders", "velvet.toml": "velvet",
           "weave-twill.toml": "weave", "paint.toml": "paint",
           "flat-lambertian.toml": "flat", "mesh-example.toml": "mesh"}
BUDGET = ["--memory-limit", "0.1"]
EXAMPLES = 100
ACCEPTED_EXAMPLES = 40
FUZZ = settings(max_examples=EXAMPLES, deadline=timedelta(seconds=60), derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

EXTREME = [0, -1, 1, 2, 3, 0.5, 1e-300, 1e-9, 1e-6, 1e-3, 0.999, 1.0000001, 89.9, 90,
           359.9, 360, 1e6, 1e9, 1e300, -1e300, math.nan, math.inf, -math.inf, 10**20,
           2**63, 4096, 8192]
values = st.one_of(
    st.sampled_from(EXTREME),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-10**12, max_value=10**12),
    st.text(max_size=6),
    st.booleans(),
    st.lists(st.one_of(st.sampled_from(EXTREME), st.floats(-1e3, 1e3)), max_size=4),
)


def toml_value(value) -> str:
    """A value as ``--set`` reads it (TOML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(value)


def keys_of(kind: str) -> dict[str, Key | None]:
    """Every key a recipe of this surface kind can set, with its schema entry (None for
    ``material.kind`` and for names that are no key)."""
    keys: dict[str, Key | None] = {f"surface.{k}": v
                                   for k, v in SURFACES[kind].keys().items()}
    keys.update({f"simulation.{k}": v for k, v in SIMULATION.items()})
    keys.update({f"table.{k}": v for k, v in TABLE.items()})
    keys.update({f"material.{k}": v for kind_keys in MATERIAL_KINDS.values()
                 for k, v in kind_keys.items()})
    return {**keys, "material.kind": None, "surface.nosuchkey": None, "nosection.key": None}


def in_range(key: Key) -> st.SearchStrategy:
    """Values the schema accepts for ``key``, its bounds included: accepted input at its
    extremes is where silent NaN hides."""
    def number(integer: bool) -> st.SearchStrategy:
        low = -1e12 if key.low is None else key.low
        high = 1e12 if key.high is None else key.high
        if integer:
            return st.integers(int(math.ceil(low)), int(high))
        edges = [v for v, open_ in ((low, key.low_open), (high, key.high_open)) if not open_]
        inside = st.floats(low, high, exclude_min=key.low_open, exclude_max=key.high_open)
        return st.one_of(st.sampled_from(edges), inside) if edges else inside

    if key.kind == "bool":
        return st.booleans()
    if key.kind in ("str", "path"):
        return st.sampled_from(list(key.choices) or ["tile-gaussian-64.ply", "missing.ply",
                                                     "../README.md"])
    if key.kind == "int":
        return number(True)
    if key.kind == "float":
        return number(False)
    size = {"rgb": 3, "pair": 2}.get(key.kind, key.length)
    lists = st.lists(number(False), min_size=size or 1, max_size=size or 4)
    return st.one_of(number(False), lists) if key.kind == "rgb" else lists


@st.composite
def overrides(draw) -> tuple[str, list[str]]:
    """A shipped recipe and 1-3 ``--set`` overrides of its keys: mostly values the schema
    accepts (its bounds included), sometimes extreme or malformed ones."""
    name = draw(st.sampled_from(sorted(RECIPES)))
    keys = keys_of(RECIPES[name])
    sets = []
    for _ in range(draw(st.integers(1, 3))):
        key = draw(st.sampled_from(sorted(keys)))
        if key == "material.kind":
            sets.append(f"{key}={draw(st.sampled_from(sorted(MATERIAL_KINDS) + ['x']))}")
            continue
        accepted = [in_range(keys[key])] * 3 if keys[key] is not None else []
        owner = [k for k, names in MATERIAL_KINDS.items() if key[len("material."):] in names]
        if key.startswith("material.") and owner:  # a key of that material's kind
            sets.append(f"material.kind={draw(st.sampled_from(owner))}")
        sets.append(f"{key}={toml_value(draw(st.one_of(*accepted, values)))}")
    return name, sets


def output_path(folder: Path, how: str, suffix: str) -> str:
    """An output path of a kind users give: fine, under a file, a folder, unicode..."""
    (folder / "a-file").write_text("x")
    (folder / f"a-folder{suffix}").mkdir(exist_ok=True)
    return str({"fine": folder / f"out{suffix}",
                "new folders": folder / "new" / "deeper" / f"out{suffix}",
                "under a file": folder / "a-file" / f"out{suffix}",
                "a folder": folder / f"a-folder{suffix}",
                "wrong suffix": folder / "out.txt",
                "unicode and spaces": folder / f"ünï cödé{suffix}",
                "impossible": Path("/proc/microsim") / f"out{suffix}"}[how])


PATHS = st.sampled_from(["fine", "new folders", "under a file", "a folder", "wrong suffix",
                         "unicode and spaces", "impossible"])


def check_outcome(code: int, err: str) -> None:
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = [line for line in err.strip().splitlines()
                 if not line.startswith("warning:")]
        assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err


def check_table(path: Path) -> None:
    """A written table: finite values, albedo and lost energy; NaN errors only in empty
    bins."""
    import microsim

    table = microsim.read_table(path)
    for c in ("total", "single"):
        assert np.isfinite(table[c].values).all(), c
        assert np.isfinite(table[c].albedo).all(), c
        empty = table[c].values == 0
        assert not (np.isnan(table[c].errors) & ~empty).any(), c
    assert np.isfinite(table.lost_energy).all()


@FUZZ
@given(recipe=overrides(), command=st.sampled_from(["check", "generate", "simulate",
                                                    "simulate", "g1", "ndf"]),
       where=st.one_of(st.just("fine"), st.just("fine"), PATHS))
def test_recipe_values_exit_0_or_2_and_tables_hold_no_nan(cli, recipe, command, where):
    name, sets = recipe
    args = [a for s in sets for a in ("--set", s)]
    source = str(ROOT / "surfaces" / name)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        argv = {"check": ["check", source],
                "generate": ["generate", source, "-o", output_path(folder, where, ".ply"),
                             *BUDGET],
                "simulate": ["simulate", source, "-o", output_path(folder, where, ".exr"),
                             "--rays", "100", *BUDGET, "--json"],
                "g1": ["measure", "g1", source, "--rays", "300", "--theta", "0,60",
                       *BUDGET, "--json"],
                "ndf": ["measure", "ndf", source, *BUDGET, "--json"]}[command]
        code, out, err = cli(*argv, *args)
        check_outcome(code, err)
        if code == 0 and command != "check":
            json.loads(out) if "--json" in argv else None
        if code == 0 and command == "simulate":
            check_table(Path(argv[argv.index("-o") + 1]))


@st.composite
def accepted(draw) -> tuple[str, list[str]]:
    """A shipped recipe and 1-2 overrides of its surface, simulation or table keys with
    values each key accepts (cross-key rules may still refuse them)."""
    name = draw(st.sampled_from(sorted(RECIPES)))
    keys = {k: v for k, v in keys_of(RECIPES[name]).items()
            if v is not None and k.split(".")[0] in ("surface", "simulation", "table")
            and v.kind != "path"}
    chosen = draw(st.lists(st.sampled_from(sorted(keys)), min_size=1, max_size=2,
                           unique=True))
    return name, [f"{k}={toml_value(draw(in_range(keys[k])))}" for k in chosen]


@settings(FUZZ, max_examples=ACCEPTED_EXAMPLES)
@given(recipe=accepted())
def test_accepted_values_simulate_to_tables_without_nan(cli, recipe):
    """Values the schema accepts, at its bounds too, give a finite table or one error
    line (a cross-key rule, the memory budget): never a NaN table."""
    name, sets = recipe
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "t.exr"
        code, _, err = cli("simulate", str(ROOT / "surfaces" / name), "-o", str(out),
                           "--rays", "100", *BUDGET, "--json",
                           *[a for s in sets for a in ("--set", s)])
        check_outcome(code, err)
        if code == 0:
            check_table(out)


FLAGS = {
    "--rays": ["0", "-3", "abc", "1e30", "2.5", "nan", "inf", "100", "1e2", ""],
    "--seed": ["0", "-1", "7", "1e3", "x", "99999999999999999999999"],
    "--threads": ["0", "1", "2", "-1", "many"],
    "--target-error": ["0", "-1", "0.5", "2", "nan", "x", "1e-300"],
    "--max-rays": ["0", "150", "1e40", "x"],
    "--theta-i": ["0", "45", "89.99", "90", "-1", "nan", "inf", "x"],
    "--theta": ["0", "0,45,89", "90", "91", "-1", ",", "nan", "0,,60"],
    "--phi": ["0", "45", "-720", "nan", "inf", "x"],
    "--bins": ["0", "1", "30", "-2", "x"],
    "--memory-limit": ["0", "-1", "1e-9", "0.05", "nan", "inf", "x"],
    "--model": ["beckmann", "ggx:alpha=0", "beckmann:alpha=nan", "lambertian:albedo=2",
                "nosuchmodel", "beckmann:alpha=1e-300", "oren-nayar:sigma=1e300", ":"],
    "--component": ["total", "single", "both"],
    "--format": ["npz", "merl", "rgl", "png"],
    "--resolution": ["1", "2", "16", "1e9", "x"],
    "--orders": ["0", "2,4", "99", "-1", "x"],
    "--window": ["none", "hanning", "boxcar"],
    "--wavelet": ["haar", "db2", "bior2.2", "dmey", "x"],
    "--keep": ["0", "1", "5", "1e9", "x"],
    "--steps": ["0", "1", "3", "x"],
    "--basis": ["table", "sh", "wavelet", "x"],
}
COMMANDS = {
    "simulate": (["--rays", "--seed", "--threads", "--target-error", "--max-rays",
                  "--memory-limit"], ".exr"),
    "measure g1": (["--rays", "--theta", "--phi", "--seed", "--threads", "--memory-limit"],
                   None),
    "measure ndf": (["--bins", "--seed", "--memory-limit"], None),
    "generate": (["--seed", "--memory-limit"], ".ply"),
    "compare": (["--model", "--component"], None),
    "export": (["--format", "--component", "--resolution", "--memory-limit"], ".npz"),
    "sh": (["--orders", "--window", "--component"], None),
    "view": (["--theta-i", "--model", "--memory-limit"], ".png"),
    "wavelets": (["--target-error", "--keep", "--component", "--resolution", "--wavelet",
                  "--steps"], ".exr"),
    "eval": (["--basis", "--component"], None),
}


@pytest.fixture(scope="module")
def fuzz_table(tmp_path_factory) -> Path:
    """A small table with harmonics to feed the commands that read one."""
    from microsim.cli import main

    path = tmp_path_factory.mktemp("fuzz") / "t.exr"
    assert main(["simulate", str(ROOT / "surfaces" / "gaussian-0.3.toml"), "--set",
                 "surface.resolution=32", "--set", "simulation.theta_i=[0, 60]", "--set",
                 "table.theta_bins=8", "--set", "table.phi_bins=16", "--set",
                 "table.sh_order=4", "--rays", "2000", "-o", str(path), "--json"]) == 0
    return path


@FUZZ
@given(data=st.data(), command=st.sampled_from(sorted(COMMANDS)), where=PATHS)
def test_flags_and_output_paths_exit_0_or_2(cli, fuzz_table, data, command, where):
    names, suffix = COMMANDS[command]
    flags = data.draw(st.lists(st.sampled_from(names), max_size=3, unique=True))
    args = [a for f in flags for a in (f, data.draw(st.sampled_from(FLAGS[f])))]
    recipe = str(ROOT / "surfaces" / "gaussian-0.3.toml")
    small = ["--set", "surface.resolution=32", "--set", "simulation.theta_i=[0, 60]"]
    with tempfile.TemporaryDirectory() as tmp:
        out = output_path(Path(tmp), where, suffix) if suffix else None
        if out is not None and command == "export":
            out = str(Path(out).with_suffix({"merl": ".binary", "rgl": ".bsdf"}.get(
                args[args.index("--format") + 1] if "--format" in args else "npz",
                ".npz")))
        argv = {
            "simulate": ["simulate", recipe, *small, "-o", out, *BUDGET],
            "measure g1": ["measure", "g1", recipe, *small],
            "measure ndf": ["measure", "ndf", recipe, *small],
            "generate": ["generate", recipe, *small, "-o", out],
            "compare": ["compare", str(fuzz_table), "--json"],
            "export": ["export", str(fuzz_table), "-o", out],
            "sh": ["sh", str(fuzz_table), "--json"],
            "view": ["view", str(fuzz_table), "--screenshot", out],
            "wavelets": ["wavelets", str(fuzz_table), "--json", "--store", out],
            "eval": ["eval", str(fuzz_table), "--wi", "30,0", "--wo", "30,180", "--json"],
        }[command]
        if command in ("simulate", "measure g1") and "--rays" not in flags:
            argv += ["--rays", "100"]  # small work unless the rays are under test
        if command == "export" and "--format" not in flags:
            argv += ["--format", "npz"]
        code, out_text, err = cli(*argv, *args)
        check_outcome(code, err)
        if code == 0 and command == "simulate":
            check_table(Path(out))
        if code == 0 and "--json" in argv:
            json.loads(out_text)
