"""Camera, lights and object around one BSDF, rendered by Mitsuba 3's path tracer.

World frame: +z up, the object at the origin (``objects.RADIUS`` = 1.45). The camera
looks at the origin from ``elevation`` degrees above the horizon at ``azimuth`` degrees
about +z (−90°: from −y), far enough that the object fills the shorter side of the image.

Lights (``--light KIND:key=value,...``, repeatable; ``LIGHTS`` lists the keys):

- ``sun``: a directional light of ``irradiance`` (RGB, W/m² on a surface facing it) from
  ``elevation`` degrees above the horizon and ``azimuth`` degrees about +z measured from
  the camera's side (0: from behind the camera, 90: from its right, 180: against it);
- ``sky``: a constant environment of ``radiance`` (RGB) from every direction;
- ``envmap``: an environment image (``file``, EXR or HDR, latitude-longitude, +z up)
  times ``scale``.

The default, ``DEFAULT_LIGHTS``, is a sun of irradiance 3 from 50° up and 40° to the
camera's left, with a sky of radiance 0.25: the sun draws the highlights, and the sky,
whose irradiance on any upward face is π × 0.25 ≈ 0.79, keeps shadowed parts visible.

Each pixel is the mean of ``spp`` independent samples through a box filter (path tracing
with next-event estimation and multiple importance sampling, ``MAX_DEPTH`` = 4 vertices:
up to three bounces between parts of the object). The renderer also returns the second
moment of every pixel's luminance, so each pixel carries its own standard error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microsim.analytic.registry import split_spec
from microsim.errors import InputError
from microsim.geometry import direction
from microsim.render.bsdfs import rgb_spectrum
from microsim.render.objects import RADIUS, Surface, corner_arrays
from microsim.schema import Key, Value, check_section, suggest

MAX_DEPTH = 4
PASS_SPP = 16
"""Samples per pixel of one pass of a render (``render``): a progress report after each."""
SUN_DISTANCE = 1000.0
"""Distance of a sun of finite size (``radius``), in units of the object (radius 1.45):
its direction varies by under 0.1° over the object."""
DEFAULT_LIGHTS = ("sun:elevation=50,azimuth=-40,irradiance=3", "sky:radiance=0.25")
LIGHTS: dict[str, dict[str, Key]] = {
    "sun": {
        "elevation": Key("float", 50.0, "Height above the horizon.", unit="deg", low=-90.0,
                         high=90.0),
        "azimuth": Key("float", -40.0, "About +z from the camera's side (90: its right).",
                       unit="deg", low=-360.0, high=360.0),
        "irradiance": Key("rgb", 3.0, "Irradiance on a surface facing the sun.", low=0.0,
                          high=1e6),
        "radius": Key("float", 0.0, "Angular radius of the sun's disc (0: a directional "
                      "light).", unit="deg", low=0.0, high=45.0),
    },
    "sky": {"radiance": Key("rgb", 0.25, "Radiance from every direction.", low=0.0,
                            high=1e6)},
    "envmap": {"file": Key("path", None, "Latitude-longitude image (EXR, HDR), +z up."),
               "scale": Key("float", 1.0, "Factor on the image.", low=0.0, high=1e6)},
}


@dataclass(frozen=True)
class Camera:
    """A perspective camera aimed at the origin.

    Attributes
    ----------
    width, height : int
        Pixels.
    elevation, azimuth : float
        Degrees: above the horizon, and about +z (−90: from −y).
    fov : float
        Degrees across the shorter side of the image.
    """

    width: int = 320
    height: int = 240
    elevation: float = 30.0
    azimuth: float = -90.0
    fov: float = 30.0

    def origin(self) -> list[float]:
        """Where the camera stands: the object's bounding sphere fills 90% of the fov."""
        distance = RADIUS / math.sin(math.radians(self.fov) / 2) / 0.9
        return (distance * _towards(self.elevation, self.azimuth)).tolist()

    def up(self) -> list[float]:
        """The image's up direction: +z, except straight above or below the object,
        where +z is the view axis itself and the horizontal direction +z tends to there
        takes its place (away from the camera's azimuth above, towards it below)."""
        elevation, azimuth = math.radians(self.elevation), math.radians(self.azimuth)
        if abs(math.cos(elevation)) > 1e-9:
            return [0.0, 0.0, 1.0]
        side = -math.copysign(1.0, math.sin(elevation))
        return [side * math.cos(azimuth), side * math.sin(azimuth), 0.0]


def _towards(elevation: float, azimuth: float) -> np.ndarray:
    """The unit vector ``elevation`` degrees above the horizon at ``azimuth`` about +z."""
    return direction(math.radians(90.0 - elevation), math.radians(azimuth))


IMAGE_MAGIC = (b"v/1\x01", b"#?RADIANCE", b"#?RGBE", b"PF\n", b"Pf\n", b"\x89PNG",
               b"\xff\xd8\xff")
"""The first bytes of the image files an environment map may be (OpenEXR, Radiance HDR,
PFM, PNG, JPEG): anything else made Mitsuba's parser raise after the scene was built."""


@dataclass(frozen=True)
class Light:
    """A light of the scene (``--light``, ``parse_light``).

    Attributes
    ----------
    kind : str
        ``"sun"``, ``"sky"`` or ``"envmap"``: a key of ``LIGHTS``.
    params : dict of str to Value
        Its keys (``LIGHTS[kind]``), checked, with the defaults filled in.
    """

    kind: str
    params: dict[str, Value]

    def to_json(self) -> dict[str, Any]:
        """The light as a ``--json`` summary writes it: ``kind`` and the parameters."""
        return {"kind": self.kind, **self.params}


def parse_light(spec: str) -> Light:
    """``KIND[:key=value,...]`` to the light, its parameters checked (defaults filled)."""
    kind, given = split_spec(spec, "--light")
    if kind not in LIGHTS:
        raise InputError(f"--light {kind!r}: unknown{suggest(kind, LIGHTS)}; lights: "
                         + ", ".join(LIGHTS))
    params = check_section(given, LIGHTS[kind], f"--light {kind}: ")
    if kind == "envmap":
        if "file" not in params:
            raise InputError("--light envmap: give file=PATH (an EXR or HDR image)")
        if not Path(params["file"]).is_file():
            raise InputError(f"--light envmap: file {params['file']!r} does not exist")
        with open(params["file"], "rb") as f:
            start = f.read(16)
        if not start.startswith(IMAGE_MAGIC):
            raise InputError(f"--light envmap: file {params['file']!r} is not an image "
                             "(an EXR or HDR environment map; PFM, PNG and JPEG read too)")
    return Light(kind, params)


def light_dicts(lights: Sequence[Light], camera: Camera) -> dict[str, Any]:
    """Mitsuba emitter dicts for parsed lights (``parse_light``)."""
    out: dict[str, Any] = {}
    for k, light in enumerate(lights):
        kind, p = light.kind, light.params
        if kind == "sun" and p.get("radius", 0.0) > 0.0:
            out[f"light{k}"] = _sun_disc(_towards(p["elevation"], camera.azimuth
                                                  + p["azimuth"]), p["irradiance"],
                                         p["radius"])
        elif kind == "sun":
            towards = _towards(p["elevation"], camera.azimuth + p["azimuth"])
            out[f"light{k}"] = {"type": "directional", "direction": (-towards).tolist(),
                                "irradiance": rgb_spectrum(p["irradiance"])}
        elif kind == "sky":
            out[f"light{k}"] = {"type": "constant", "radiance": rgb_spectrum(p["radiance"])}
        else:
            out[f"light{k}"] = {"type": "envmap", "filename": str(p["file"]),
                                "scale": p["scale"],
                                "to_world": _z_up()}
    return out


def _sun_disc(towards: np.ndarray, irradiance: list[float], radius_deg: float
              ) -> dict[str, Any]:
    """A sun of angular radius ρ = ``radius_deg`` and irradiance E (RGB): a uniform disc
    ``SUN_DISTANCE`` away facing the object, of radius D tan ρ (so it spans a cone of
    half-angle ρ) and radiance E / (π sin²ρ), which gives irradiance E on a surface facing
    it (``live.disc_radiance``)."""
    import mitsuba as mi

    from microsim.render.live import disc_radiance

    radius = math.radians(radius_deg)
    up = [1.0, 0.0, 0.0] if abs(towards[2]) > 0.99 else [0.0, 0.0, 1.0]
    place = mi.ScalarTransform4f().look_at(origin=(SUN_DISTANCE * towards).tolist(),
                                           target=[0.0, 0.0, 0.0], up=up)
    return {"type": "disk",
            "to_world": place @ mi.ScalarTransform4f().scale(SUN_DISTANCE
                                                             * math.tan(radius)),
            "emitter": {"type": "area", "radiance": rgb_spectrum(
                disc_radiance(irradiance, radius_deg))}}


def _z_up() -> Any:
    import mitsuba as mi

    # Mitsuba's envmap has +y up; turn it so the image's top is +z
    return mi.ScalarTransform4f().rotate([1.0, 0.0, 0.0], 90.0)


def mesh(mi: Any, surface: Surface, bsdf: Any) -> Any:
    """A Mitsuba mesh of ``surface`` with ``bsdf``, its shading frames along the surface's
    tangents (``objects.corner_arrays``)."""
    positions, normals, uvs, faces = corner_arrays(surface)
    props = mi.Properties()
    props["bsdf"] = bsdf
    m = mi.Mesh(surface.name, len(positions), len(faces), props=props,
                has_vertex_normals=True, has_vertex_texcoords=True)
    params = mi.traverse(m)
    for key, array in (("vertex_positions", positions), ("vertex_normals", normals),
                       ("vertex_texcoords", uvs), ("faces", faces)):
        params[key] = type(params[key])(array.ravel())  # the variant's array type
    params.update()
    return m


def scene(mi: Any, surface: Surface, bsdf: Any, camera: Camera,
          lights: Sequence[Light], spp: int, seed: int) -> Any:
    """The Mitsuba scene: path tracer with luminance moments, camera, lights, object."""
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "moment", "nested": {
            "type": "path", "max_depth": MAX_DEPTH, "hide_emitters": True}},
        "sensor": {
            "type": "perspective", "fov": camera.fov, "fov_axis": "smaller",
            "to_world": mi.ScalarTransform4f().look_at(origin=camera.origin(),
                                                       target=[0.0, 0.0, 0.0],
                                                       up=camera.up()),
            "film": {"type": "hdrfilm", "width": camera.width, "height": camera.height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgba"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed}},
        **light_dicts(lights, camera),
        "object": mesh(mi, surface, bsdf),
    })


@dataclass(frozen=True)
class Image:
    """A rendered image.

    Attributes
    ----------
    rgb : (h, w, 3) float
        Linear radiance, premultiplied by coverage (0 where no ray hit the object).
    alpha : (h, w) float
        Coverage of the object.
    luminance, luminance_err : (h, w) float
        Mean luminance Y of the pixel's samples and its standard error √((E[Y²] − Y²)/spp).
    seconds : float
        Wall time of the render.
    """

    rgb: np.ndarray
    alpha: np.ndarray
    luminance: np.ndarray
    luminance_err: np.ndarray
    seconds: float


def render(mi: Any, surface: Surface, bsdf: Any, camera: Camera,
           lights: Sequence[Light], spp: int, seed: int = 0,
           progress: Callable[[int, int], None] | None = None) -> Image:
    """Render ``surface`` with ``bsdf`` and return the image with per-pixel errors.

    The samples are taken in passes of at most ``PASS_SPP`` per pixel, pass k seeded from
    ``SeedSequence(seed, spawn_key=(k,))``; the image is their mean and its second moment
    theirs, so it is one render of ``spp`` samples, the same whether or not anyone
    watches. ``progress(done, spp)`` is called after every pass.
    """
    import time

    sc = scene(mi, surface, bsdf, camera, lights, spp, seed)
    start = time.perf_counter()
    total = None
    for k, first in enumerate(range(0, spp, PASS_SPP)):
        n = min(PASS_SPP, spp - first)
        pass_seed = int(np.random.SeedSequence(seed, spawn_key=(k,)).generate_state(1)[0])
        data = np.array(mi.render(sc, seed=pass_seed, spp=n), dtype=float) * n
        total = data if total is None else total + data
        if progress is not None:
            progress(first + n, spp)
    data = total / spp
    seconds = time.perf_counter() - start
    # channels: R, G, B, A, nested.X, .Y, .Z, m2_nested.X, .Y, .Z (moments in CIE XYZ)
    y, y2 = data[..., 5], data[..., 8]
    err = np.sqrt(np.maximum(y2 - y**2, 0.0) / spp)
    return Image(data[..., :3], data[..., 3], y, err, seconds)
