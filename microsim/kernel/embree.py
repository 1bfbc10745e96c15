"""Embree 4 called from compiled code: the transport kernel's ray queries.

The kernel asks Embree for each segment's closest hit itself, through Embree's C API
(``rtcIntersect1``), so a path goes from query to query without returning to Python. The
Embree used is the one ``embreex`` ships (its wheel bundles ``libembree4``): ``library``
finds it beside the installed ``embreex`` package and loads it with ``ctypes``, and
``Scene`` builds a scene of one triangle mesh with it. Compiled code receives the address
of ``rtcIntersect1`` as an integer and calls it through ``call3`` (an LLVM indirect call),
so the compiled kernel holds no process-specific address and stays cacheable.

Every scene of a process comes from one Embree device (``device``: made on first use; a
device starts Embree's build threads), and shares its vertex and index arrays with Embree
(``rtcSetSharedGeometryBuffer``) instead of copying them into Embree's own buffers. A scene
can take new positions for the same vertices and faces (``Scene.update``: the realisations
of a height field on one grid) and then refits its BVH, about 2 ms instead of a 16 ms
build for 131 072 triangles: Embree refits a geometry of build quality
``RTC_BUILD_QUALITY_REFIT`` in a scene of quality ``RTC_BUILD_QUALITY_LOW`` (its two-level
structure, where geometries keep their own quality) with ``RTC_SCENE_FLAG_DYNAMIC``
(without the flag it rebuilds); Embree's documentation, ``rtcSetGeometryBuildQuality`` and
``rtcSetSceneFlags``. Measured on that tile (docs/goniometer.md, "The Embree scene"): built
anew, the same hits at the same speed as Embree's default build; refitted, 1–2% more time
per query, and a float32 tie where a ray meets an edge two faces share may be answered
with the other face (16 of 12 million first hits).

The ray-hit record is Embree 4's ``RTCRayHit`` (``rtcore_ray.h``): 16-byte aligned, the
ray's origin, ``tnear``, direction, ``time``, ``tfar`` (float32), ``mask``, ``id``,
``flags`` (uint32), then the hit's geometric normal, u, v (float32), ``primID``,
``geomID``, ``instID`` (uint32); ``R_*`` are the 4-byte word offsets of those fields.
"""

from __future__ import annotations

import atexit
import ctypes
import ctypes.util
import os
import threading
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
"""``RTC_GEOMETRY_TYPE_TRIANGLE`` (``rtcore_geometry.h``), ``RTC_BUFFER_TYPE_INDEX``,
``RTC_BUFFER_TYPE_VERTEX`` (``rtcore_buffer.h``)."""
_UINT3, _FLOAT3 = 0x5003, 0x9003
"""``RTC_FORMAT_UINT3``, ``RTC_FORMAT_FLOAT3`` (``rtcore_common.h``)."""
_QUALITY_LOW, _QUALITY_REFIT = 0, 3
"""``RTC_BUILD_QUALITY_LOW``, ``RTC_BUILD_QUALITY_REFIT`` (``enum RTCBuildQuality``,
``rtcore_common.h``)."""
_SCENE_DYNAMIC = 1
"""``RTC_SCENE_FLAG_DYNAMIC`` (``enum RTCSceneFlags``, ``rtcore_scene.h``)."""
_VERSION = 0
"""``RTC_DEVICE_PROPERTY_VERSION`` (``rtcore_device.h``): major · 10000 + minor · 100 +
patch."""


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
            ("rtcSetSceneBuildQuality", None, [size, ctypes.c_int]),
            ("rtcSetSceneFlags", None, [size, ctypes.c_int]),
            ("rtcCommitScene", None, [size]),
            ("rtcNewGeometry", size, [size, ctypes.c_int]),
            ("rtcSetGeometryBuildQuality", None, [size, ctypes.c_int]),
            ("rtcSetSharedGeometryBuffer", None,
             [size, ctypes.c_int, ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, size, size,
              size]),
            ("rtcUpdateGeometryBuffer", None, [size, ctypes.c_int, ctypes.c_uint]),
            ("rtcCommitGeometry", None, [size]),
            ("rtcAttachGeometry", ctypes.c_uint, [size, size]),
            ("rtcReleaseGeometry", None, [size])):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = result, args


_LIB: ctypes.CDLL | None = None
_DEVICE: tuple[int, int] | None = None
"""(process id, ``RTCDevice``) of this process's device."""
_DEVICE_LOCK = threading.Lock()


def _lib() -> ctypes.CDLL:
    global _LIB
    if _LIB is None:
        _LIB = library()
    return _LIB


def device() -> int:
    """This process's Embree device (``RTCDevice``), made on first use, thread-safe.

    A forked child makes its own (a device's build threads do not survive a fork). The
    process's reference is released at exit; scenes hold references of their own
    (Embree's objects are reference counted), so one still open then stays valid.

    Raises
    ------
    RuntimeError
        If Embree cannot create a device.
    """
    global _DEVICE
    with _DEVICE_LOCK:
        if _DEVICE is None or _DEVICE[0] != os.getpid():
            lib = _lib()
            handle = lib.rtcNewDevice(None)
            if not handle:
                raise RuntimeError("Embree could not create a device")
            _DEVICE = (os.getpid(), handle)
            atexit.register(_release_device, handle)
        return _DEVICE[1]


def _release_device(handle: int) -> None:
    """Drop this process's reference to its device (at exit)."""
    global _DEVICE
    if _DEVICE is not None and _DEVICE == (os.getpid(), handle):
        _lib().rtcReleaseDevice(handle)
        _DEVICE = None


class Scene:
    """One triangle mesh in an Embree 4 scene, committed and ready for ``rtcIntersect1``.

    The scene reads its vertices and faces from arrays it keeps (float32 and uint32
    copies, shared with Embree), and refits its BVH when given new vertex positions
    (``update``).

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
    faces : (m, 3) int
        The ``faces`` array given (the object itself, to recognise the same topology).
    vertex_count : int
        n.

    Raises
    ------
    RuntimeError
        If Embree reports an error while building the scene.
    """

    handle = 0  # until made (so that close is safe on a failed construction)

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        lib = self._lib = _lib()
        self._device = device()
        self.version = int(lib.rtcGetDeviceProperty(self._device, _VERSION))
        self.faces, self.vertex_count = faces, len(vertices)
        # float3 vertex buffers are read with 16-byte loads: one float of padding at the
        # end (Embree's documentation, rtcSetSharedGeometryBuffer)
        self._vertices = np.zeros(3 * len(vertices) + 1, np.float32)
        self._indices = np.ascontiguousarray(faces, np.uint32)
        self.handle = lib.rtcNewScene(self._device)
        lib.rtcSetSceneBuildQuality(self.handle, _QUALITY_LOW)
        lib.rtcSetSceneFlags(self.handle, _SCENE_DYNAMIC)
        self._geometry = lib.rtcNewGeometry(self._device, _TRIANGLE)
        lib.rtcSetGeometryBuildQuality(self._geometry, _QUALITY_REFIT)
        for kind, fmt, data, count in ((_VERTEX, _FLOAT3, self._vertices, len(vertices)),
                                       (_INDEX, _UINT3, self._indices, len(faces))):
            lib.rtcSetSharedGeometryBuffer(self._geometry, kind, 0, fmt, data.ctypes.data,
                                           0, 12, count)
        self._check("could not share the mesh's buffers")
        lib.rtcAttachGeometry(self.handle, self._geometry)
        self.update(vertices)
        self.intersect = ctypes.cast(lib.rtcIntersect1, ctypes.c_void_p).value

    def update(self, vertices: np.ndarray) -> None:
        """Move the vertices and refit the BVH (the faces stay); not while queries run.

        Parameters
        ----------
        vertices : (n, 3) float
            New positions of the scene's n vertices.

        Raises
        ------
        ValueError
            If the number of vertices differs.
        RuntimeError
            If the scene is closed, or Embree reports an error while committing it.
        """
        if not self.handle:
            raise RuntimeError("the Embree scene is closed")
        if len(vertices) != self.vertex_count:
            raise ValueError(f"the scene has {self.vertex_count} vertices, not "
                             f"{len(vertices)}")
        self._vertices[:-1] = np.ravel(vertices)
        lib = self._lib
        lib.rtcUpdateGeometryBuffer(self._geometry, _VERTEX, 0)
        lib.rtcCommitGeometry(self._geometry)
        lib.rtcCommitScene(self.handle)
        self._check("failed to build the scene")

    def _check(self, what: str) -> None:
        """Raise ``RuntimeError`` if the device reports an error."""
        error = self._lib.rtcGetDeviceError(self._device)
        if error:
            raise RuntimeError(f"Embree {what} (error {error})")

    def close(self) -> None:
        """Release the scene (the device stays for the next)."""
        if self.handle:
            self._lib.rtcReleaseGeometry(self._geometry)
            self._lib.rtcReleaseScene(self.handle)
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
