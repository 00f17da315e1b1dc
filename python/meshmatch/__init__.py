"""meshmatch: example-based texturing of 3D meshes, from Python.

numpy in, numpy out. Meshes are :class:`Mesh` objects (``meshmatch.load(path)`` or
``Mesh(vertices, faces, colors=None, uvs=None, texture=None)``); each system is one function with
the command-line tool's parameters and defaults (flags as keyword arguments, ``-`` as ``_``):

>>> import meshmatch
>>> spot = meshmatch.load("spot.obj")
>>> bunny = meshmatch.load("bunny.obj")
>>> out = meshmatch.transfer(spot, bunny, vertices=8000)
>>> out.colors.shape
(3301, 3)

Long calls release the GIL, report ``progress(fraction, stage)`` to an optional callback, and
stop on a :class:`CancelToken` (raising :class:`Cancelled`) or on Ctrl-C (raising
``KeyboardInterrupt``). Refusals and failures raise :class:`MeshMatchError` with the CLI's
one-line message.
"""

from ._native import (
    Cancelled,
    CancelToken,
    Mesh,
    MeshMatchError,
    bake,
    complete,
    curves,
    detail,
    feature_maps,
    features,
    load,
    quilt,
    synthesize,
    transfer,
    update,
    weather,
)

__version__ = "0.1.0"

__all__ = [
    "Cancelled",
    "CancelToken",
    "Mesh",
    "MeshMatchError",
    "bake",
    "complete",
    "curves",
    "detail",
    "feature_maps",
    "features",
    "load",
    "quilt",
    "synthesize",
    "transfer",
    "update",
    "weather",
]
