"""Count ``dict[str, Any]`` / ``Mapping[str, Any]`` in the argument and return annotations
of microsim/ (run from the repository root), split into:

- json-named: functions whose name contains "json" (to_json, from_json, ...);
- serialisation: the functions listed in SERIALISATION below, whose mapping is raw parsed
  TOML/JSON coming in, or a JSON/TOML-ready document (or a Mitsuba ``load_dict``
  dictionary, or an EXR header attribute) going out;
- remaining: everything else, the untyped records between modules.

    python scripts/untyped_mappings.py [-v] [-s]

A function is named by file and qualified name (``Class.method``, ``outer.inner``).
``-v`` lists the remaining ones, ``-s`` the serialisation ones found.
"""

from __future__ import annotations

import ast
import pathlib
import sys

SERIALISATION = {
    # raw parsed TOML in: recipe parsing
    ("microsim/__init__.py", "load_recipe"): "source: a recipe's parsed TOML (or its path)",
    ("microsim/recipe.py", "_table"): "a recipe section as parsed TOML",
    ("microsim/recipe.py", "resolve"): "the parsed recipe TOML",
    ("microsim/recipe.py", "_wavelength_range"): "the parsed [table] TOML section",
    ("microsim/recipe.py", "resolve_in"): "the parsed recipe TOML",
    ("microsim/schema.py", "parse_kind"): "raw: a parsed TOML section",
    ("microsim/schema.py", "check_section"): "raw: a parsed TOML section",
    ("microsim/surfaces/__init__.py", "parse_surface"): "the parsed [surface] TOML",
    ("microsim/surfaces/base.py", "Surface.parse"): "the parsed [surface] TOML",
    ("microsim/materials/__init__.py", "parse_material"): "the parsed [material] TOML",
    ("microsim/materials/base.py", "Material.parse"): "the parsed [material] TOML",
    ("microsim/spectra/dispersion.py", "Sellmeier._from_fields"): "a parsed TOML/JSON table",
    ("microsim/spectra/dispersion.py", "Cauchy._from_fields"): "a parsed TOML/JSON table",
    # raw parsed JSON in: table file headers, batch manifests
    ("microsim/tables/validation.py", "_components"): "a table file's parsed JSON header",
    ("microsim/tables/validation.py", "_channels"): "a table file's parsed JSON header",
    ("microsim/tables/validation.py", "check_header"): "a table file's parsed JSON header",
    ("microsim/batch.py", "read_manifest"): "the parsed manifest.json",
    ("microsim/batch.py", "Manifest.__init__"): "manifest.json's table entries",
    # JSON-ready documents out: --json summaries, file headers, Mitsuba dicts
    ("microsim/commands/simulate.py", "summary"): "what simulate --json prints",
    ("microsim/commands/simulate.py", "print_summary"): "the simulate --json document, as text",
    ("microsim/commands/bench.py", "summary"): "what bench --json prints",
    ("microsim/commands/generate.py", "tile_facts"): "what generate --json prints",
    ("microsim/tables/wavelets.py", "part_header"): "a JSON attribute of a table file",
    ("microsim/render/bsdfs.py", "rgb_spectrum"): "a Mitsuba load_dict dict",
    ("microsim/render/bsdfs.py", "_spectrum"): "a Mitsuba load_dict dict",
    ("microsim/render/bsdfs.py", "mitsuba_equivalent"): "a Mitsuba load_dict dict",
    ("microsim/render/scene.py", "light_dicts"): "Mitsuba load_dict emitter dicts",
    ("microsim/render/scene.py", "_sun_disc"): "a Mitsuba load_dict emitter dict",
    ("microsim/render/spectral.py", "spectrum_dict"): "a Mitsuba load_dict dict",
}


def functions(tree: ast.AST, prefix: str = ""):
    """(qualified name, node) of every function, methods and nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield prefix + node.name, node
            yield from functions(node, prefix + node.name + ".")
        elif isinstance(node, ast.ClassDef):
            yield from functions(node, prefix + node.name + ".")
        else:
            yield from functions(node, prefix)


rows = []
for p in sorted(pathlib.Path("microsim").rglob("*.py")):
    for qualname, node in functions(ast.parse(p.read_text())):
        a = node.args
        for arg in [*a.posonlyargs, *a.args, *a.kwonlyargs, None]:
            ann = node.returns if arg is None else arg.annotation
            if ann is None:
                continue
            s = ast.unparse(ann)
            if "dict[str, Any]" in s or "Mapping[str, Any]" in s:
                rows.append((str(p), node.lineno, qualname, arg.arg if arg else "return", s))

json_named = [r for r in rows if "json" in r[2].rsplit(".", 1)[-1].lower()]
rest = [r for r in rows if r not in json_named]
serialisation = [r for r in rest if (r[0], r[2]) in SERIALISATION]
remaining = [r for r in rest if (r[0], r[2]) not in SERIALISATION]
unused = sorted(set(SERIALISATION) - {(r[0], r[2]) for r in serialisation})
print(f"{len(rows)} in all: {len(json_named)} json-named, {len(serialisation)} in the "
      f"{len(SERIALISATION) - len(unused)} listed (de)serialisation functions found, "
      f"remaining {len(remaining)}")
if unused:
    print("listed but not found:", ", ".join(f"{f}:{q}" for f, q in unused))
if "-s" in sys.argv:
    for r in serialisation:
        print(*r, SERIALISATION[(r[0], r[2])], sep="  ")
if "-v" in sys.argv:
    for r in remaining:
        print(*r, sep="  ")
