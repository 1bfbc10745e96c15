"""Embree 4 called from compiled code: the transport kernel's ray queries.

The kernel asks Embree for each segment's closest hit itself, through Embree's C API
(``rtcIntersect1``), so a path goes from query to query without returning to Python. The
Embree used is the one ``embreex`` ships (its wheel bundles ``libembree4``): ``library``
finds it beside the installed ``embreex`` package and loads it with ``ctypes``, and
``Scene`` builds a scene of one triangle mesh with it. Compiled code receives the address
of ``rtcIntersect1`` as an integer and calls it through ``call3`` (an LLVM indirect call),
so the compiled kernel holds no process-specific address and stays cacheable.

The ray-hit record is Embree 4's ``RTCRayHit`` (``rtcore_ray.h``): 16-byte aligned, the
ray's origin, ``tnear``, direction, ``time``, ``tfar`` (float32), ``mask``, ``id``,
``flags`` (uint32), then the hit's geometric normal, u, v (float32), ``primID``,
``geomID``, ``instID`` (uint32); ``R_*`` are the 4-byte word offsets of those fields.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from pathlib import Path

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

(R_ORG_X, R_ORG_Y, R_ORG_Z, R_TNEAR, R_DIR_X, R_DIR_Y, R_DIR_Z, R_TIME, R_TFAR, R_MASK,
 R_ID, R_FLAGS, R_NG_X, R_NG_Y, R_NG_Z, R_U, R_V, R_PRIM, R_GEOM, R_INST) = range(20)
"""Word offsets of ``RTCRayHit``'s fields."""
RAYHIT_WORDS = 24
"""Words reserved for one record (80 bytes used; room for ``instPrimID``)."""
INVALID = 0xFFFFFFFF
"""``RTC_INVALID_GEOMETRY_ID``: no hit."""
_TRIANGLE, _INDEX, _VERTEX = 0, 0, 1
"""``RTC_GEOMETRY_TYPE_TRIANGLE``, ``RTC_BUFFER_TYPE_INDEX``, ``RTC_BUFFER_TYPE_VERTEX``."""
_UINT3, _FLOAT3 = 0x5003, 0x9003
"""``RTC_FORMAT_UINT3``, ``RTC_FORMAT_FLOAT3``."""
_VERSION = 0
"""``RTC_DEVICE_PROPERTY_VERSION``: major · 10000 + minor · 100 + patch."""


def library() -> ctypes.CDLL:
    """The Embree 4 library ``embreex`` loads (from its wheel's bundled libraries).

    Raises
    ------
    ImportError
        If no ``libembree4`` is found beside ``embreex`` or on the library path.
    """
    import embreex

    package = Path(embreex.__file__).resolve().parent
    candidates = [p for folder in (package.parent / "embreex.libs", package / ".dylibs",
                                   package)
                  for p in sorted(folder.glob("*embree4*")) if p.is_file()]
    found = ctypes.util.find_library("embree4")
    if found:
        candidates.append(Path(found))
    for path in candidates:
        try:
            lib = ctypes.CDLL(str(path))
        except OSError:
            continue
        _declare(lib)
        if lib.rtcGetDeviceProperty is not None:
            return lib
    raise ImportError("microsim needs Embree 4 as embreex installs it (libembree4 beside "
                      "the embreex package); reinstall embreex")


def _declare(lib: ctypes.CDLL) -> None:
    """Argument and result types of the C functions used (handles as ``size_t``)."""
    size = ctypes.c_size_t
    for name, result, args in (
            ("rtcNewDevice", size, [ctypes.c_char_p]),
            ("rtcGetDeviceError", ctypes.c_int, [size]),
            ("rtcGetDeviceProperty", ctypes.c_ssize_t, [size, ctypes.c_int]),
            ("rtcReleaseDevice", None, [size]),
            ("rtcNewScene", size, [size]),
            ("rtcReleaseScene", None, [size]),
            ("rtcCommitScene", None, [size]),
            ("rtcNewGeometry", size, [size, ctypes.c_int]),
            ("rtcSetNewGeometryBuffer", size,
             [size, ctypes.c_int, ctypes.c_uint, ctypes.c_int, size, size]),
            ("rtcCommitGeometry", None, [size]),
            ("rtcAttachGeometry", ctypes.c_uint, [size, size]),
            ("rtcReleaseGeometry", None, [size])):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = result, args


_LIB: ctypes.CDLL | None = None


def _lib() -> ctypes.CDLL:
    global _LIB
    if _LIB is None:
        _LIB = library()
    return _LIB


class Scene:
    """One triangle mesh in an Embree 4 scene, committed and ready for ``rtcIntersect1``.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions (stored as float32).
    faces : (m, 3) int
        Vertex indices per triangle.

    Attributes
    ----------
    handle : int
        The ``RTCScene``.
    intersect : int
        The address of ``rtcIntersect1``.
    version : int
        Embree's version, major · 10000 + minor · 100 + patch.

    Raises
    ------
    RuntimeError
        If Embree reports an error while building the scene.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        lib = _lib()
        self._lib = lib
        self._device = lib.rtcNewDevice(None)
        if not self._device:
            raise RuntimeError("Embree could not create a device")
        self.version = int(lib.rtcGetDeviceProperty(self._device, _VERSION))
        self.handle = lib.rtcNewScene(self._device)
        geometry = lib.rtcNewGeometry(self._device, _TRIANGLE)
        for kind, fmt, ctype, data in ((_VERTEX, _FLOAT3, ctypes.c_float,
                                        np.asarray(vertices, np.float32)),
                                       (_INDEX, _UINT3, ctypes.c_uint,
                                        np.asarray(faces, np.uint32))):
            address = lib.rtcSetNewGeometryBuffer(geometry, kind, 0, fmt, 12, len(data))
            if not address:
                raise RuntimeError(f"Embree could not allocate a buffer "
                                   f"(error {lib.rtcGetDeviceError(self._device)})")
            view = (ctype * data.size).from_address(address)
            np.ctypeslib.as_array(view)[:] = np.ascontiguousarray(data).ravel()
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(self.handle, geometry)
        lib.rtcReleaseGeometry(geometry)
        lib.rtcCommitScene(self.handle)
        error = lib.rtcGetDeviceError(self._device)
        if error:
            raise RuntimeError(f"Embree failed to build the scene (error {error})")
        self.intersect = ctypes.cast(lib.rtcIntersect1, ctypes.c_void_p).value

    def close(self) -> None:
        """Release the scene and its device."""
        if self.handle:
            self._lib.rtcReleaseScene(self.handle)
            self._lib.rtcReleaseDevice(self._device)
            self.handle = 0

    def __del__(self) -> None:
        self.close()


def rayhit_buffer() -> np.ndarray:
    """A zeroed 16-byte-aligned ``RTCRayHit`` record: (RAYHIT_WORDS,) float32 (view its
    words as uint32 for the integer fields)."""
    raw = np.zeros(RAYHIT_WORDS + 4, np.float32)
    skip = (-raw.ctypes.data % 16) // 4
    return raw[skip:skip + RAYHIT_WORDS]


@intrinsic
def call3(typingctx, fn, a, b, c):  # noqa: ANN001, ANN201 (numba intrinsic signature)
    """Call the C function at address ``fn`` with three pointer-sized arguments, from
    compiled code: ``void fn(void*, void*, void*)`` (``rtcIntersect1(scene, rayhit,
    NULL)``)."""
    sig = types.void(types.uintp, types.uintp, types.uintp, types.uintp)

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202
        word = ir.IntType(64)
        target = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [word] * 3)
                                  .as_pointer())
        builder.call(target, list(args[1:]))
        return context.get_dummy_value()

    return sig, codegen
