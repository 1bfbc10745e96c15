"""Mutation testing of the physics and statistics modules with mutmut, one module at a time.

Usage::

    python scripts/mutation_test.py [--modules PATH ...] [--work DIR] [--list]
        [--summary]

Each module is mutated in its own copy of the committed tree (``git archive HEAD``, so
edits in the working tree do not leak in and the run can be repeated) under ``--work``
(default ``/tmp/microsim-mutation``), with ``[tool.mutmut]`` set to mutate that module
only and to run the fast tests that cover it (``MODULES``), smallest modules first, under
``nice -n 19`` and one mutant at a time (the machine's cores are shared). Before each
module the run waits while the file ``/work/QUIET`` exists (a benchmark is running).
mutmut picks, per mutant, the tests of the selection that execute the mutated function,
and skips functions with decorators (the numba kernels, ``@dataclass`` methods).

Per module it writes ``<work>/<name>.json``: mutmut's counts (killed, survived, no
tests, timeout, ...), the score killed / (killed + survived + no tests) and every
survivor with its diff. ``--summary`` prints the Markdown table of all the modules run so
far (for docs/testing.md). Not part of ``pytest``: a run over every module takes hours on
two cores.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tarfile
import time
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
QUIET = Path("/work/QUIET")

MATERIAL_TESTS = ["tests/test_recipe.py", "tests/test_model_parameters.py",
                  "tests/test_dielectric.py", "tests/test_thin_film.py",
                  "tests/test_spectra.py", "tests/test_black.py"]
"""The fast tests of the materials' records (parsing, parameters, Fresnel records, model
defaults); their scattering is kernel language, which mutmut does not mutate."""

DESELECT_WARNING = ("--deselect=tests/test_tables_table.py::"
                    "test_damaged_harmonics_are_a_warning_or_with_require_sh_an_error")
"""Checks that read_table's warning names its caller's file, which under mutmut is its
trampoline (the clean run fails and mutmut stops); its other checks are in the others."""

MODULES: dict[str, list[str]] = {
    "microsim/tables/interpolation.py": ["tests/test_tables_table.py"],
    "microsim/tables/components.py": ["tests/test_orders.py::test_component_names",
                                      "tests/test_tables_table.py"],
    "microsim/analytic/fresnel.py": ["tests/test_analytic_brdf.py"],
    "microsim/analytic/shadowing.py": ["tests/test_analytic_brdf.py",
                                       "tests/test_analytic_ndf.py"],
    "microsim/analytic/layered.py": [
        "tests/test_dielectric.py::test_internal_reflectance_quadrature_is_consistent",
        "tests/test_dielectric.py::test_coated_lambertian_model_agrees_with_the_quadrature"],
    "microsim/comparison/agreement.py": [
        "tests/test_robustness.py::test_verdict_follows_the_error_bars",
        "tests/test_robustness.py::test_agreement_bounds_are_the_documented_quantiles",
        "tests/test_compare.py"],
    "microsim/tables/binning.py": ["tests/test_tables_binning.py",
                                   "tests/test_tables_table.py"],
    "microsim/analytic/visible_normals.py": ["tests/test_multiple_scattering.py"],
    "microsim/analytic/cloth.py": ["tests/test_fibre_models.py"],
    "microsim/analytic/velvet.py": ["tests/test_fibre_models.py"],
    "microsim/analytic/cylinders.py": ["tests/test_fibre_models.py"],
    "microsim/analytic/ndf.py": ["tests/test_analytic_ndf.py"],
    "microsim/comparison/fit.py": ["tests/test_fit.py",
                        # the fibre models' fits (_kay_kajiya, _microcylinder, _ClothPerChannel)
                        "tests/test_fit_fibres.py",
                        # a whole simulation (30 s) for each mutant of fit_table that
                        # survives the fast tests, which test what it tests
                        "--deselect=tests/test_fit.py::"
                        "test_simulated_gaussian_fits_beckmann_at_its_realised_alpha"],
    "microsim/analytic/multiple_scattering.py": ["tests/test_multiple_scattering.py"],
    "microsim/analytic/brdf.py": ["tests/test_analytic_brdf.py",
                                  # flat_pairs and as_rgb serve the fibre models and compare
                                  "tests/test_fibre_models.py", "tests/test_compare.py"],
    "microsim/analytic/registry.py": ["tests/test_models_cli.py",
                                      "tests/test_analytic_brdf.py",
                                      "tests/test_model_registry.py"],
    "microsim/comparison/metrics.py": ["tests/test_compare.py",
                            "tests/test_robustness.py::test_verdict_follows_the_error_bars"],
    "microsim/tables/estimator.py": [
        "tests/test_ensemble.py::test_inverse_trigamma_inverts_trigamma",
        "tests/test_ensemble.py::"
        "test_inverse_trigamma_beyond_newtons_range_is_the_asymptotic_form",
        "tests/test_ensemble.py::test_moderation_prior_recovers_a_known_prior",
        "tests/test_ensemble.py::"
        "test_running_sums_give_the_two_pass_estimates_and_the_group_jackknife",
        "tests/test_ensemble.py::"
        "test_estimate_of_sums_is_the_documented_formulas_and_sums_merge",
        "tests/test_ensemble.py::"
        "test_inverse_trigamma_is_the_root_across_newtons_range",
        "tests/test_ensemble.py::"
        "test_moderation_prior_of_ratios_scattering_exactly_as_sampling_does",
        "tests/test_ensemble.py::"
        "test_realisation_moments_of_absent_and_one_ray_realisations",
        "tests/test_ensemble.py::"
        "test_batch_means_alone_and_sums_taken_and_absorbed",
        "tests/test_ensemble.py::"
        "test_batch_mean_sums_keep_one_group_however_many_realisations",
        "tests/test_ensemble.py::"
        "test_moderated_estimate_of_few_realisations_is_its_formulas",
        "tests/test_ensemble.py::"
        "test_moderated_estimate_where_replicates_tie_or_lose_their_ray_variance",
        "tests/test_ensemble.py::"
        "test_moderated_estimate_of_sparse_realisations",
        "tests/test_tables_table.py"],
    "microsim/tables/sh.py": ["tests/test_sh.py"],
    "microsim/tables/sh_matrix.py": ["tests/test_sh.py"],
    "microsim/tables/sh_error.py": ["tests/test_sh_error.py", "tests/test_sh.py"],
    "microsim/tables/table.py": ["tests/test_brdf_table.py", "tests/test_tables_table.py",
                                 "tests/test_sh.py",
                                 "tests/test_wavelets.py", "tests/test_table_input.py",
                                 "tests/test_export.py"],
    "microsim/tables/assemble.py": ["tests/test_tables_table.py", "tests/test_ensemble.py",
                                    "tests/test_sh.py", "tests/test_tables_assemble.py",
                                    # 256 realisations (150 s under mutmut) for each
                                    # mutant of the ensemble's sums that survives the
                                    # rest; its running sums are tested by the fast ones
                                    "--deselect=tests/test_ensemble.py::"
                                    "test_memory_does_not_grow_with_the_realisations"],
    "microsim/tables/evaluate.py": ["tests/test_evaluate.py", "tests/test_export.py",
                                    "tests/test_compare.py",
                                    "tests/test_tables_table.py", "tests/test_wavelets.py"],
    "microsim/tables/meta.py": ["tests/test_tables_table.py", "tests/test_table_input.py",
                                "tests/test_export.py"],
    "microsim/tables/validation.py": ["tests/test_table_input.py",
                                      "tests/test_tables_table.py", DESELECT_WARNING],
    "microsim/tables/exr.py": ["tests/test_table_input.py", "tests/test_tables_table.py",
                               "tests/test_sh.py", "tests/test_wavelets.py",
                               DESELECT_WARNING],
    "microsim/tables/export.py": ["tests/test_export.py", "tests/test_spectral_export.py",
                                  "tests/test_export_formats.py"],
    "microsim/tables/luminance.py": ["tests/test_luminance.py", "tests/test_colour.py",
                                     "tests/test_spectral_export.py"],
    "microsim/tables/equal_area.py": ["tests/test_wavelets.py"],
    "microsim/tables/compression.py": ["tests/test_wavelets.py"],
    "microsim/tables/wavelets.py": ["tests/test_wavelets.py"],
    "microsim/materials/optics.py": ["tests/test_dielectric.py"],
    "microsim/materials/table.py": [*MATERIAL_TESTS, "tests/test_tabulated.py"],
    "microsim/materials/thin_film.py": MATERIAL_TESTS,
    **{f"microsim/materials/{name}.py": MATERIAL_TESTS
       for name in ("__init__", "base", "black", "coating", "conductor", "dielectric",
                    "lambertian", "mirror")},
}
"""Each module of the run and the fast tests that cover it (pytest node ids, and
``--deselect`` for a slow test of a file that adds nothing its fast tests do not)."""

SCORED = ("killed", "survived", "no_tests")


def lines(path: str) -> int:
    """Lines of a module of the committed tree."""
    return len(subprocess.run(["git", "show", f"HEAD:{path}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout.splitlines())


def committed_tree(dest: Path) -> None:
    """The committed tree (HEAD) unpacked into ``dest``."""
    archive = subprocess.run(["git", "archive", "HEAD"], cwd=ROOT, check=True,
                             capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(dest, filter="data")


def configure(tree: Path, module: str, tests: list[str]) -> None:
    """Append mutmut's settings for ``module`` to the copy's pyproject.toml."""
    quoted = ", ".join(json.dumps(t) for t in tests)
    with (tree / "pyproject.toml").open("a", encoding="utf-8") as f:
        f.write(f"\n[tool.mutmut]\nsource_paths = [\"microsim\"]\n"
                f"only_mutate = [{json.dumps(module)}]\n"
                f"pytest_add_cli_args_test_selection = [{quoted}]\n"
                "pytest_add_cli_args = [\"-p\", \"no:cacheprovider\", \"-q\"]\n"
                "also_copy = [\"surfaces/\", \"tables/\", \"scripts/\", \"docs/\", "
                "\"README.md\"]\n")


def survivors(tree: Path, env: dict[str, str]) -> list[dict[str, str]]:
    """The mutants that survived (or had no tests), each with its diff."""
    out = subprocess.run(["mutmut", "results"], cwd=tree, env=env, capture_output=True,
                         text=True).stdout
    found = []
    for line in out.splitlines():
        name, _, status = line.strip().rpartition(": ")
        if status in ("survived", "no tests"):
            diff = subprocess.run(["mutmut", "show", name], cwd=tree, env=env,
                                  capture_output=True, text=True).stdout
            found.append({"mutant": name, "status": status, "diff": diff})
    return found


def run_module(module: str, tests: list[str], work: Path) -> dict:
    """Mutate one module in a fresh copy of the tree; its counts, score and survivors."""
    name = module.removeprefix("microsim/").removesuffix(".py").replace("/", ".")
    tree = work / name
    shutil.rmtree(tree, ignore_errors=True)
    tree.mkdir(parents=True)
    committed_tree(tree)
    configure(tree, module, tests)
    # mutmut puts <tree>/mutants first on sys.path itself; a PYTHONPATH naming it before
    # it exists would leave a cached miss there, and the tests would import the original
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    while QUIET.exists():
        time.sleep(15)
    start = time.perf_counter()
    subprocess.run(["nice", "-n", "19", "mutmut", "run", "--max-children", "1"], cwd=tree,
                   env=env, check=False)
    wall = time.perf_counter() - start
    subprocess.run(["mutmut", "export-cicd-stats"], cwd=tree, env=env, check=False)
    # mutmut stops before writing any result when it generated no mutant (every function
    # of the module decorated, as the kernel-language functions of materials/optics.py)
    stats_file = tree / "mutants" / "mutmut-cicd-stats.json"
    stats = json.loads(stats_file.read_text()) if stats_file.exists() else {"total": 0}
    scored = sum(stats.get(k, 0) for k in SCORED)
    result = {"module": module, "tests": tests, "lines": lines(module), "stats": stats,
              "score": stats.get("killed", 0) / scored if scored else None,
              "wall_s": round(wall), "survivors": survivors(tree, env)}
    (work / f"{name}.json").write_text(json.dumps(result, indent=1), encoding="utf-8")
    return result


def summary(work: Path) -> str:
    """Markdown rows of every module run so far under ``work``."""
    rows = ["| module | lines | mutants | killed | survived | no tests | timeout | score |"
            " wall |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for path in sorted(work.glob("*.json"), key=lambda p: json.loads(p.read_text())["lines"]):
        r = json.loads(path.read_text())
        s = r["stats"]
        score = "–" if r["score"] is None else f"{100 * r['score']:.1f}%"
        rows.append(f"| `{r['module']}` | {r['lines']} | {s.get('total', 0)} | "
                    f"{s.get('killed', 0)} | {s.get('survived', 0)} | "
                    f"{s.get('no_tests', 0)} | {s.get('timeout', 0)} | {score} | "
                    f"{r['wall_s']} s |")
    return "\n".join(rows)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--modules", nargs="*", default=None,
                        help="modules to run (default: all of MODULES, smallest first)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/microsim-mutation"))
    parser.add_argument("--list", action="store_true", help="list the modules and tests")
    parser.add_argument("--summary", action="store_true",
                        help="print the Markdown table of the modules run so far")
    args = parser.parse_args()
    if args.summary:
        print(summary(args.work))
        return 0
    chosen = args.modules or list(MODULES)
    unknown = [m for m in chosen if m not in MODULES]
    if unknown:
        print(f"error: --modules: {', '.join(unknown)} not among {', '.join(MODULES)}",
              file=sys.stderr)
        return 2
    chosen.sort(key=lines)
    if args.list:
        for m in chosen:
            print(f"{lines(m):5d} {m}: {' '.join(MODULES[m])}")
        return 0
    args.work.mkdir(parents=True, exist_ok=True)
    for module in chosen:
        r = run_module(module, MODULES[module], args.work)
        print(f"{module}: {r['stats']} score {r['score']}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
