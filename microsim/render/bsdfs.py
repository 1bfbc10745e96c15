"""A table or an analytic model as a Mitsuba 3 BSDF.

**Tables** go through Mitsuba's own ``measured`` plugin: ``table.eval`` is resampled onto
an RGL tensor (``microsim.tables.export.rgl_tensor``) with dense incidences, so Mitsuba's
interpolation between them follows the table's own (linear in θi and φi at fixed ωo).
Anisotropic tables get a slice every 15° of φi with the half-vector azimuth measured from
the tangent. Mitsuba looks a BSDF up with the direction towards the camera as its first
argument; the tensor is written with the arguments swapped, so the value it returns is
f_r(ωi = light, ωo = viewer) cos θ_light, microsim's convention, even for a table that is
not exactly reciprocal.

**Models** use Mitsuba's own plugin when one computes the same function
(``mitsuba_equivalent``): ``diffuse`` for ``lambertian``; ``roughconductor`` for a
Beckmann or GGX microfacet model with separable Smith masking (Mitsuba's) and a conductor
or no Fresnel term (F = 1: ``material = none``); ``roughplastic`` with no diffuse layer for
an isotropic one with a dielectric Fresnel term. Everything else is tabulated as a table
is (``tensor_bsdf``) where the caller gives a file for it — the render command does in
scalar variants, where a Python call per direction pair would take minutes — or else
evaluated by numpy through a Python BSDF (``python_bsdf``), sampled cosine-weighted.

**Channels.** A table's or a model's channels are R, G, B or the wavelengths of a
spectral table (``wavelengths``); each BSDF gets what its variant renders
(``microsim.render.spectral``): a spectral table in a spectral variant keeps its
wavelengths (``measured`` reads the spectral RGL layout), in an RGB variant it is its
linear sRGB; an RGB table in a spectral variant is upsampled as Mitsuba upsamples RGB.
A model's equivalent plugin gets per-wavelength parameters as Mitsuba spectra where the
plugin computes the same function per wavelength (a conductor's η and k, a Lambertian
albedo); in an RGB variant a per-wavelength Fresnel term has no RGB equivalent (the sRGB
of F(η(λ), k(λ)) is not F of any RGB η, k), nor in a spectral variant an RGB one (Mitsuba
would upsample η and k, not f_r), so such models are tabulated or evaluated by numpy and
their f_r converted like a table's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microsim.analytic.brdf import as_rgb
from microsim.errors import InputError
from microsim.render.spectral import (
    at_wavelengths,
    coefficients,
    for_variant,
    per_channel,
    spectral_variant,
    spectrum_dict,
    upsampled,
)
from microsim.tables.export import rgl_phi_i, rgl_tensor, srgb_linear, write_tensor_file

THETA_NODES = {True: 32, False: 16}
"""Incidences of the resampled tensor (isotropic, anisotropic), uniform over [0, 89°]."""
RESOLUTION = {True: 64, False: 48}
"""Half-vector grid vertices per axis (isotropic, anisotropic)."""
PHI_STEP = 15.0
"""Degrees between the φi slices of an anisotropic tensor."""


def tensor_pairs(isotropic: bool) -> int:
    """Direction pairs at which ``tensor_bsdf`` evaluates f (isotropic or not)."""
    slices = 1 if isotropic else len(rgl_phi_i(PHI_STEP))
    return slices * THETA_NODES[isotropic] * RESOLUTION[isotropic] ** 2


def rotation_z(degrees: float) -> np.ndarray:
    """The 3 × 3 rotation by ``degrees`` about +z (counter-clockwise seen from above)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def oriented(f: Any, rotation: float) -> Any:
    """``f`` rotated by ``rotation`` degrees about the normal and called camera-first.

    Parameters
    ----------
    f : callable
        ``f(wi, wo) -> (..., 3)`` in microsim's order (light, viewer).
    rotation : float
        Degrees; the material's +x axis turns from the tangent towards the bitangent.

    Returns
    -------
    callable
        ``g(a, b) = f(R⁻¹ b, R⁻¹ a)`` for ``a`` towards the camera and ``b`` towards the
        light, as Mitsuba calls a BSDF.
    """
    inverse = rotation_z(-rotation)
    return lambda a, b: f(b @ inverse.T, a @ inverse.T)


def tensor_bsdf(mi: Any, f: Any, isotropic: bool, path: str | Path, rotation: float,
                description: str, wavelengths: Sequence[float] | None = None) -> Any:
    """Write f_r as an RGL tensor at ``path`` and load it with ``measured``.

    Parameters
    ----------
    mi : module
        Mitsuba, variant set.
    f : callable
        ``f(wi, wo) -> (..., C)`` (or (...)) f_r in 1/sr for (..., 3) unit directions.
    isotropic : bool
        Whether f depends on the azimuths only through their difference (one φi slice).
    path : str or Path
        Where the ``.bsdf`` goes (a temporary file of the caller).
    rotation : float
        Degrees about the normal (anisotropic f; an isotropic one is unchanged).
    description : str
        The tensor's description field.
    wavelengths : (C,) float or None
        The channels of f: None for R, G, B. They become the variant's
        (``microsim.render.spectral.for_variant``): a spectral tensor in a spectral
        variant, an RGB one in an RGB variant.
    """
    g, nm, _ = for_variant(mi, f, wavelengths)
    fields = rgl_tensor(oriented(g, rotation),
                        np.radians(np.linspace(0.0, 89.0, THETA_NODES[isotropic])),
                        None if isotropic else rgl_phi_i(PHI_STEP), RESOLUTION[isotropic],
                        description, nm)
    write_tensor_file(fields, path)
    return mi.load_dict({"type": "measured", "filename": str(path)})


def table_bsdf(mi: Any, table: Any, path: str | Path, component: str = "total",
               rotation: float = 0.0) -> Any:
    """``table``'s ``component`` through ``measured`` (``tensor_bsdf``), in the channels
    of the variant (its wavelengths, its sRGB, or its RGB upsampled)."""
    return tensor_bsdf(mi, lambda wi, wo: table.eval(wi, wo, component),
                       bool(table.isotropic), path, rotation, f"microsim {component} table",
                       table.channels.wavelengths)


def isotropic(f: Any, pairs: int = 256, seed: int = 0) -> bool:
    """Whether ``f(wi, wo)`` is unchanged when both directions turn about the normal:
    checked at ``pairs`` random direction pairs each turned by a random angle (relative
    difference ≤ 1e-9 of the largest value)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, pairs, 3))
    v[..., 2] = np.abs(v[..., 2])  # upper hemisphere
    wi, wo = v / np.linalg.norm(v, axis=-1, keepdims=True)
    turn = rotation_z(float(rng.uniform(10.0, 350.0)))
    a = as_rgb(f(wi, wo), (pairs,))
    b = as_rgb(f(wi @ turn.T, wo @ turn.T), (pairs,))
    return bool(np.all(np.abs(a - b) <= 1e-9 * max(float(np.abs(a).max()), 1e-300)))


def rgb_spectrum(value: Any) -> dict[str, Any]:
    """A Mitsuba ``rgb`` spectrum dict from one value or three (R, G, B)."""
    v = np.broadcast_to(np.asarray(value, float), (3,))
    return {"type": "rgb", "value": [float(x) for x in v]}


def _uniform(value: Any) -> float | None:
    """The one number every channel of ``value`` holds, or None if they differ."""
    v = np.ravel(np.asarray(value, float))
    return float(v[0]) if v.size and np.all(v == v[0]) else None


def _spectrum(value: Any, wavelengths: Sequence[float] | None, spectral: bool,
              linear: bool) -> dict[str, Any] | float | None:
    """A plugin parameter of per-channel ``value`` for the variant, or None where the
    plugin would not compute the same function.

    A number is the same everywhere: an ``rgb`` dict in an RGB variant, a plain float
    (Mitsuba's ``uniform`` spectrum) in a spectral one, where an ``rgb`` dict would be
    upsampled (and one above 1, such as an η of 1.5, came back as 0 from
    ``roughconductor`` in ``scalar_spectral``); three numbers of an RGB model are an
    ``rgb`` dict in an RGB variant only; per-wavelength numbers are an ``irregular``
    spectrum in a spectral variant, or, where the plugin is ``linear`` in the parameter
    (a Lambertian albedo), their linear sRGB in an RGB variant.
    """
    one = _uniform(value)
    if one is not None:
        return one if spectral else rgb_spectrum(one)
    if wavelengths is None:
        return None if spectral else rgb_spectrum(value)
    v = np.ravel(np.asarray(value, float))
    if spectral:
        return spectrum_dict(wavelengths, v)
    return rgb_spectrum(srgb_linear(wavelengths, v)) if linear else None


def mitsuba_equivalent(model: Any, rotation: float = 0.0,
                       wavelengths: Sequence[float] | None = None,
                       spectral: bool = False) -> dict[str, Any] | None:
    """The dict of Mitsuba's own plugin that computes ``model``, or None.

    Parameters
    ----------
    model : object
        A model of ``microsim.analytic`` (``parse_model_spec``'s third value).
    rotation : float
        Degrees about the normal. Isotropic models ignore it; an anisotropic one maps to
        ``roughconductor`` only at multiples of 90° (which swap α_u and α_v).
    wavelengths : (C,) float or None
        What the model's per-channel parameters are: None for R, G, B, or these
        wavelengths (a spectral table's).
    spectral : bool
        Whether the variant is spectral.

    Returns
    -------
    dict or None
    """
    from microsim.analytic.brdf import Lambertian, TorranceSparrow
    from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel
    from microsim.analytic.ndf import GGX, Beckmann

    if isinstance(model, Lambertian):
        albedo = model.albedo
        if wavelengths is None and spectral and _uniform(albedo) is None:
            return {"type": "diffuse", "reflectance": rgb_spectrum(albedo)}  # upsampled
        reflectance = _spectrum(albedo, wavelengths, spectral, linear=True)
        return None if reflectance is None else {"type": "diffuse",
                                                 "reflectance": reflectance}
    if not (isinstance(model, TorranceSparrow) and model.shadowing == "smith-separable"
            and type(model.ndf) in (Beckmann, GGX)):
        return None
    ax, ay = model.ndf.alpha_x, model.ndf.alpha_y
    quarter = (rotation / 90.0) % 2
    if ax != ay:
        if not float(quarter).is_integer():
            return None
        ax, ay = (ay, ax) if quarter == 1 else (ax, ay)
    rough: dict[str, Any] = {"distribution": "beckmann" if type(model.ndf) is Beckmann
                             else "ggx"}
    rough.update({"alpha": ax} if ax == ay else {"alpha_u": ax, "alpha_v": ay})
    fresnel = model.fresnel
    if fresnel is None:
        return {"type": "roughconductor", "material": "none", **rough}
    if isinstance(fresnel, ConductorFresnel):
        eta = _spectrum(fresnel.eta, wavelengths, spectral, linear=False)
        k = _spectrum(fresnel.k, wavelengths, spectral, linear=False)
        if eta is None or k is None:
            return None
        return {"type": "roughconductor", "eta": eta, "k": k, **rough}
    eta = _uniform(fresnel.eta) if isinstance(fresnel, DielectricFresnel) else None
    if eta is not None and ax == ay:
        return {"type": "roughplastic", "int_ior": eta, "ext_ior": 1.0,
                "diffuse_reflectance": rgb_spectrum(0.0), "nonlinear": False, **rough}
    return None


def model_channels(model: Any, wavelengths: Sequence[float] | None, where: str) -> None:
    """Check that ``model`` gives one value or one per channel of its table.

    Raises
    ------
    InputError
        A model whose per-channel parameters do not fit the table's channels: three
        values (R, G, B) for a spectral table of another number of wavelengths, or
        parameters of different lengths (a spec's three beside the table's sixteen).
    """
    count = 3 if wavelengths is None else len(wavelengths)
    what = "R, G, B" if wavelengths is None else f"the table's {count} wavelengths"
    hint = (f"{where}: its per-channel parameters must be one number or one per channel "
            f"({what})")
    w = np.array([[0.3, 0.1, 0.95], [-0.2, 0.25, 0.9]])
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    try:
        value = np.asarray(model.eval(w[:1], w[1:]), float)
    except ValueError:  # numpy cannot broadcast channels of different lengths
        raise InputError(f"{hint}; they have different lengths") from None
    if value.ndim < 2 or value.shape[-1] in (1, count):
        return
    if value.shape[-1] == 3 and np.all(value == value[..., :1]):
        return  # one number given, which the spec makes R, G, B: grey (per_channel)
    raise InputError(f"{hint}; it gives {value.shape[-1]} values per direction pair")


def model_bsdf(mi: Any, model: Any, rotation: float = 0.0,
               path: str | Path | None = None,
               wavelengths: Sequence[float] | None = None) -> tuple[Any, str]:
    """Mitsuba's equivalent plugin if there is one; else the model tabulated as a table is
    (``tensor_bsdf``) when ``path`` is given, or the Python BSDF.

    ``wavelengths`` says what the model's channels are (None: R, G, B; else a spectral
    table's wavelengths); each way converts them to the variant's as a table's are.

    Returns
    -------
    bsdf : mitsuba.BSDF
    how : str
        The plugin's name, ``"tabulated"`` or ``"python"``.
    """
    plugin = mitsuba_equivalent(model, rotation, wavelengths, spectral_variant(mi))
    if plugin is not None:
        return mi.load_dict(plugin), plugin["type"]
    if path is not None:
        return tensor_bsdf(mi, model.eval, isotropic(model.eval), path, rotation,
                           f"microsim model {type(model).__name__}",
                           wavelengths), "tabulated"
    return python_bsdf(mi, model, rotation, wavelengths), "python"


def _numpy(v: Any) -> np.ndarray:
    """A Mitsuba 3-vector (scalar or array) as (3,) or (n, 3) float64."""
    a = np.array(v, dtype=float)
    return a.T if a.ndim == 2 else a


def python_bsdf(mi: Any, model: Any, rotation: float = 0.0,
                wavelengths: Sequence[float] | None = None) -> Any:
    """``model`` evaluated by numpy inside a Mitsuba BSDF.

    ``eval`` returns f_r(ωi = light, ωo = viewer) cos θ_light; ``sample`` draws the light
    direction cosine-weighted (Malley's method, ``square_to_cosine_hemisphere``), so the
    weight is f_r π. Works in every variant: one direction pair per call in
    ``scalar_rgb``, whole arrays in ``llvm_ad_rgb`` and ``llvm_ad_spectral``. In a
    spectral variant the value is at the ray's four wavelengths (``si.wavelengths``): a
    per-wavelength model's (``wavelengths``) interpolated linearly between them
    (``spectral.at_wavelengths``), an RGB one's upsampled (``spectral.coefficients``, one
    Mitsuba call per pair: slow); in an RGB variant a per-wavelength model's is its
    linear sRGB.
    """
    import drjit as dr

    f = oriented(model.eval, rotation)
    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
    spectral = spectral_variant(mi)
    count = 3 if wavelengths is None else len(wavelengths)

    def spectrum(lam: Any, value: np.ndarray) -> Any:
        """Mitsuba's Spectrum of ``value`` ((count,) or (n, count)) at the rays'
        wavelengths ``lam``."""
        nm = np.array(lam, dtype=float)
        rows = value.reshape(-1, count)
        nm = np.broadcast_to(nm.T if nm.ndim == 2 else nm, (len(rows), nm.shape[0]))
        if wavelengths is None:
            coeff, scale = coefficients(mi, rows)
            out = upsampled(coeff, scale, nm)
        else:
            out = at_wavelengths(wavelengths, rows, nm)
        if value.ndim == 1:
            return mi.Spectrum(*(float(x) for x in out[0]))
        return mi.Spectrum(np.ascontiguousarray(out.T, dtype=np.float32))

    class ModelBSDF(mi.BSDF):
        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            self.m_flags = flags
            self.m_components = [flags]

        def _value(self, si: Any, wo: Any, active: Any) -> Any:
            wi = si.wi
            a, b = _numpy(wi), _numpy(wo)
            value = per_channel(f(a, b), a.shape[:-1], count) * np.maximum(b[..., 2:3], 0.0)
            if spectral:
                colour = spectrum(si.wavelengths, value)
            else:
                if wavelengths is not None:
                    value = srgb_linear(wavelengths, value)
                colour = (mi.Color3f(*value) if value.ndim == 1 else
                          mi.Color3f(np.ascontiguousarray(value.T, dtype=np.float32)))
            return dr.select(active & (wi.z > 0) & (wo.z > 0), colour, 0.0)

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any,
                   active: Any = True) -> Any:
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo, bs.pdf, bs.eta = wo, pdf, 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = 0
            value = self._value(si, wo, active & (pdf > 0))
            return bs, value / dr.maximum(pdf, 1e-20)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self._value(si, wo, active)

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return dr.select(si.wi.z > 0, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def to_string(self) -> str:
            return f"microsim model {type(model).__name__}"

    return ModelBSDF(mi.Properties())
