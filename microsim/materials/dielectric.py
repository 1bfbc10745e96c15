"""The ``dielectric`` facet: specular reflection with the dielectric Fresnel reflectance;
the refracted part leaves the simulation, or, with ``refract = true``, refracts into the
medium the part's faces enclose (absorbing per unit length) and out again."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.materials.base import Material, kernel
from microsim.materials.optics import fresnel_dielectric, reflect, refract
from microsim.schema import key


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple) -> tuple[float, ...]:
    """Column 0: η; column 3: 1 to refract.

    Refracting: a Fresnel-weighted choice between reflection and refraction with u[0],
    weight 1 either way: an unbiased estimate of both (PBR 4th ed., sec. 9.5); from inside
    the medium the ray sees 1 / η about the flipped normal. No 1/η² on crossing: a path
    carries power (importance), not radiance (Veach 1997, thesis, sec. 5.2). Otherwise a
    mirror reflection with weight F; 1 − F is transmitted (reported as lost)."""
    eta = params[part, 0]
    if params[part, 3] != 0.0:
        if dx * nx + dy * ny + dz * nz >= 0.0:
            nx, ny, nz, eta = -nx, -ny, -nz, 1.0 / eta
        f = fresnel_dielectric(-(dx * nx + dy * ny + dz * nz), eta)
        if u[0] >= f:
            tx, ty, tz, tir = refract(dx, dy, dz, nx, ny, nz, eta)
            if not tir:
                return tx, ty, tz, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0
        ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
        return ox, oy, oz, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    f = fresnel_dielectric(-(dx * nx + dy * ny + dz * nz), eta)
    return ox, oy, oz, f, f, f, 1.0 - f, 1.0 - f, 1.0 - f


@dataclass(frozen=True, kw_only=True)
class Dielectric(Material):
    """Specular reflection with dielectric Fresnel; optionally refraction into a medium."""

    kind: ClassVar[str] = "dielectric"
    doc: ClassVar[str] = (
        "Specular reflection with dielectric Fresnel; the refracted part is absorbed and "
        "reported as lost energy, or, with refract = true, refracted into the medium "
        "behind the faces (absorbing per unit length) and out again.")
    scatter: ClassVar = scatter
    blocks: ClassVar[int] = 1
    eta: float = key("float", 1.5, "Index of refraction relative to the medium in front of "
                     "the faces (air; for particles inside a paint's binder, relative to the "
                     "binder); 1 would be no interface at all.", low=1.0, low_open=True,
                     high=10.0)
    refract: bool = key("bool", False, "Refract as well as reflect: a Fresnel-weighted "
                        "choice, Snell's law, total internal reflection; the part's faces "
                        "enclose a medium behind them (docs/materials.md). false: reflect "
                        "with weight F, report 1 - F as transmitted.")
    absorption: tuple[float, float, float] = key(
        "rgb", 0.0, "Beer-Lambert absorption coefficient inside the medium, per tile unit "
        "of path length (R, G, B); needs refract = true.", low=0.0)

    def check(self, where: str) -> None:
        """Absorption needs a medium: ``refract = true``."""
        if not self.refract and any(a > 0 for a in self.absorption):
            raise InputError(f"{where}absorption = {list(self.absorption)!r}: needs refract "
                             "= true (without refraction no light enters the medium)")

    def parameters(self) -> tuple[float, ...]:
        """η (R, G, B: the same), then 1 to refract."""
        return (self.eta, self.eta, self.eta, 1.0 if self.refract else 0.0)

    def medium(self) -> tuple[float, float, float] | None:
        """The absorption inside a refracting part, None for a reflecting one."""
        return self.absorption if self.refract else None

    def fresnel(self) -> tuple | None:
        """``("dielectric", eta)``."""
        return ("dielectric", float(self.eta))

    def model_defaults(self) -> dict[str, Any]:
        """``eta``."""
        return {"eta": self.eta}
