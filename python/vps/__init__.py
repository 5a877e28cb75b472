"""vps: Voxmap-PointShell haptic data structures from Python (docs/PYTHON.md).

Meshes in, voxmaps and pointshells out, contact forces between them; numpy arrays in and out.
Every error of the library is raised as a subclass of :class:`VpsError` with the library's
message. Long calls release the GIL, so threads (and Dask workers' threads) run meanwhile.

The cluster batch of many parts at several voxel sizes is :mod:`vps.batch`.
"""

from ._vps import (
    LEAF_SIZE,
    MAX_LAYERS,
    Contact,
    GenerateError,
    HapticsError,
    Mesh,
    MeshError,
    Pointshell,
    Simulation,
    SimulationStep,
    StorageError,
    Voxmap,
    VpsError,
    contact,
    pointshell,
    voxelize,
)

__all__ = [
    "LEAF_SIZE",
    "MAX_LAYERS",
    "Contact",
    "GenerateError",
    "HapticsError",
    "Mesh",
    "MeshError",
    "Pointshell",
    "Simulation",
    "SimulationStep",
    "StorageError",
    "Voxmap",
    "VpsError",
    "contact",
    "pointshell",
    "voxelize",
]
