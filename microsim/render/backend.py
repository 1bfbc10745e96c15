"""Loading Mitsuba 3 for rendering: the ``[render]`` extra, the variant, its flags.

``scalar_rgb`` (the default) renders one ray at a time in C++ and works wherever Mitsuba's
wheel installs. ``llvm_ad_rgb`` vectorises over all rays (and so runs a Python BSDF on
whole arrays at once) but needs an LLVM library of version 16 or newer that Dr.Jit can
find (``DRJIT_LIBLLVM_PATH``): older ones abort the process while compiling, so it is
refused before. ``scalar_spectral`` and ``llvm_ad_spectral`` are their spectral
counterparts: each ray carries four wavelengths sampled over 360–830 nm and the film
integrates them to colour with the CIE 1931 2° matching functions
(``microsim.render.spectral`` says what a table becomes there). A variant must be one the
installed Mitsuba was built with (``mitsuba.variants()``).
"""

from __future__ import annotations

from typing import Any

from microsim.errors import InputError

VARIANTS = ("scalar_rgb", "llvm_ad_rgb", "scalar_spectral", "llvm_ad_spectral")
SPECTRAL = ("scalar_spectral", "llvm_ad_spectral")
MIN_LLVM = (16, 0, 0)
EXTRA_HINT = "pip install 'microsim[render]'"


def load(variant: str = "scalar_rgb") -> Any:
    """Import Mitsuba 3 and set ``variant``.

    In the LLVM variants, symbolic loops and calls are turned off so that a Python BSDF
    receives evaluated arrays it can hand to numpy.

    Raises
    ------
    InputError
        Mitsuba is not installed (the message names the ``render`` extra), the variant is
        unknown or not in this build of Mitsuba, or the LLVM library is missing or too
        old.
    """
    if variant not in VARIANTS:
        raise InputError(f"--variant {variant}: must be one of {', '.join(VARIANTS)}")
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        raise InputError("microsim render needs Mitsuba 3, which is not installed: "
                         f"{EXTRA_HINT} (the render extra)") from None
    built = tuple(mi.variants())
    if variant not in built:
        have = ", ".join(v for v in VARIANTS if v in built) or "none of them"
        raise InputError(f"--variant {variant}: this Mitsuba ({mi.__version__}) was not "
                         f"built with it; it has {have}")
    if variant.startswith("llvm"):
        version = tuple(dr.detail.llvm_version()) if dr.has_backend(dr.JitBackend.LLVM) \
            else None
        if version is None or version < MIN_LLVM:
            found = "none found" if version is None else ".".join(map(str, version))
            raise InputError(f"--variant {variant}: needs LLVM >= 16 ({found}); set "
                             "DRJIT_LIBLLVM_PATH to a newer libLLVM, or use a scalar variant")
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    mi.set_variant(variant)
    return mi
