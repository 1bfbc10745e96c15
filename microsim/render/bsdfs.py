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
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from microsim.analytic.brdf import as_rgb
from microsim.tables.export import rgl_phi_i, rgl_tensor, write_tensor_file

THETA_NODES = {True: 32, False: 16}
"""Incidences of the resampled tensor (isotropic, anisotropic), uniform over [0, 89°]."""
RESOLUTION = {True: 64, False: 48}
"""Half-vector grid vertices per axis (isotropic, anisotropic)."""
PHI_STEP = 15.0
"""Degrees between the φi slices of an anisotropic tensor."""


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
                description: str) -> Any:
    """Write f_r as an RGL tensor at ``path`` and load it with ``measured``.

    Parameters
    ----------
    mi : module
        Mitsuba, variant set.
    f : callable
        ``f(wi, wo) -> (..., 3)`` (or (...)) f_r in 1/sr for (..., 3) unit directions.
    isotropic : bool
        Whether f depends on the azimuths only through their difference (one φi slice).
    path : str or Path
        Where the ``.bsdf`` goes (a temporary file of the caller).
    rotation : float
        Degrees about the normal (anisotropic f; an isotropic one is unchanged).
    description : str
        The tensor's description field.
    """
    def rgb(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return as_rgb(f(wi, wo), np.broadcast_shapes(wi.shape, wo.shape)[:-1])

    fields = rgl_tensor(oriented(rgb, rotation),
                        np.radians(np.linspace(0.0, 89.0, THETA_NODES[isotropic])),
                        None if isotropic else rgl_phi_i(PHI_STEP), RESOLUTION[isotropic],
                        description)
    write_tensor_file(fields, path)
    return mi.load_dict({"type": "measured", "filename": str(path)})


def table_bsdf(mi: Any, table: Any, path: str | Path, component: str = "total",
               rotation: float = 0.0) -> Any:
    """``table``'s ``component`` through ``measured`` (``tensor_bsdf``)."""
    return tensor_bsdf(mi, lambda wi, wo: table.eval(wi, wo, component),
                       bool(table.isotropic), path, rotation, f"microsim {component} table")


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


def mitsuba_equivalent(model: Any, rotation: float = 0.0) -> dict[str, Any] | None:
    """The dict of Mitsuba's own plugin that computes ``model``, or None.

    Parameters
    ----------
    model : object
        A model of ``microsim.analytic`` (``parse_model_spec``'s third value).
    rotation : float
        Degrees about the normal. Isotropic models ignore it; an anisotropic one maps to
        ``roughconductor`` only at multiples of 90° (which swap α_u and α_v).

    Returns
    -------
    dict or None
    """
    from microsim.analytic.brdf import Lambertian, TorranceSparrow
    from microsim.analytic.ndf import GGX, Beckmann

    if isinstance(model, Lambertian):
        return {"type": "diffuse", "reflectance": rgb_spectrum(model.albedo)}
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
    if fresnel[0] == "conductor":
        return {"type": "roughconductor", "eta": rgb_spectrum(fresnel[1]),
                "k": rgb_spectrum(fresnel[2]), **rough}
    eta = np.ravel(fresnel[1])
    if fresnel[0] == "dielectric" and ax == ay and np.all(eta == eta[0]):
        return {"type": "roughplastic", "int_ior": float(eta[0]), "ext_ior": 1.0,
                "diffuse_reflectance": rgb_spectrum(0.0), "nonlinear": False, **rough}
    return None


def model_bsdf(mi: Any, model: Any, rotation: float = 0.0,
               path: str | Path | None = None) -> tuple[Any, str]:
    """Mitsuba's equivalent plugin if there is one; else the model tabulated as a table is
    (``tensor_bsdf``) when ``path`` is given, or the Python BSDF.

    Returns
    -------
    bsdf : mitsuba.BSDF
    how : str
        The plugin's name, ``"tabulated"`` or ``"python"``.
    """
    plugin = mitsuba_equivalent(model, rotation)
    if plugin is not None:
        return mi.load_dict(plugin), plugin["type"]
    if path is not None:
        return tensor_bsdf(mi, model.eval, isotropic(model.eval), path, rotation,
                           f"microsim model {type(model).__name__}"), "tabulated"
    return python_bsdf(mi, model, rotation), "python"


def _numpy(v: Any) -> np.ndarray:
    """A Mitsuba 3-vector (scalar or array) as (3,) or (n, 3) float64."""
    a = np.array(v, dtype=float)
    return a.T if a.ndim == 2 else a


def python_bsdf(mi: Any, model: Any, rotation: float = 0.0) -> Any:
    """``model`` evaluated by numpy inside a Mitsuba BSDF.

    ``eval`` returns f_r(ωi = light, ωo = viewer) cos θ_light; ``sample`` draws the light
    direction cosine-weighted (Malley's method, ``square_to_cosine_hemisphere``), so the
    weight is f_r π. Works in every variant: one direction pair per call in
    ``scalar_rgb`` (about 0.1 ms each, docs/render.md), whole arrays in ``llvm_ad_rgb``.
    """
    import drjit as dr

    f = oriented(model.eval, rotation)
    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide

    class ModelBSDF(mi.BSDF):
        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            self.m_flags = flags
            self.m_components = [flags]

        def _value(self, wi: Any, wo: Any, active: Any) -> Any:
            a, b = _numpy(wi), _numpy(wo)
            value = as_rgb(f(a, b), a.shape[:-1]) * np.maximum(b[..., 2:3], 0.0)
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
            value = self._value(si.wi, wo, active & (pdf > 0))
            return bs, value / dr.maximum(pdf, 1e-20)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self._value(si.wi, wo, active)

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return dr.select(si.wi.z > 0, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def to_string(self) -> str:
            return f"microsim model {type(model).__name__}"

    return ModelBSDF(mi.Properties())
