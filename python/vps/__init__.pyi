"""Type stubs of the vps package (the native module vps._vps, re-exported)."""

from os import PathLike
from typing import Iterator, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Axis = Union[int, Literal["x", "y", "z"]]

LEAF_SIZE: int
MAX_LAYERS: int

class VpsError(Exception):
    """Base class of the errors of the vps library; the message is the library's."""

class MeshError(VpsError):
    """A mesh could not be read or is unusable."""

class StorageError(VpsError):
    """A .vxm or .vps file could not be read or written."""

class GenerateError(VpsError):
    """Voxelization or pointshell generation failed."""

class HapticsError(VpsError):
    """A contact query failed."""

class Mesh:
    """A triangle mesh split into objects, degenerate triangles removed."""

    def __init__(
        self,
        vertices: npt.ArrayLike,
        triangles: npt.ArrayLike,
        name: str = "mesh",
    ) -> None:
        """One object from vertices (V, 3) and triangles (T, 3) of vertex indices."""
    @staticmethod
    def load(path: _Path) -> Mesh:
        """Load a mesh file: OBJ (or .obj.zst), STL, PLY, glTF or GLB, by extension or content; or a
        scene file (.toml), its meshes placed as one."""
    @property
    def triangle_count(self) -> int: ...
    @property
    def degenerate_skipped(self) -> int: ...
    @property
    def objects(self) -> list[str]: ...
    @property
    def bounds(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]: ...
    def triangle_array(self) -> npt.NDArray[np.float64]:
        """Corners as a (3T, 3) float64 array, three rows per triangle."""

class Voxmap:
    """A voxmap: from voxelize (in memory) or Voxmap.open (a memory-mapped .vxm)."""

    @staticmethod
    def open(path: _Path) -> Voxmap: ...
    def values(self, points: npt.ArrayLike) -> npt.NDArray[np.int8]:
        """Values of the voxels holding points (N, 3): < 0 outside, 0 surface, > 0 inside."""
    def distances(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Signed distances at points (N, 3), positive inside, trilinear as a contact reads them."""
    def slice(
        self, axis: _Axis, at: Optional[float] = None, index: Optional[int] = None
    ) -> npt.NDArray[np.int8]:
        """One slice as an int8 array (height, width), row 0 at the top, as `vps slice` draws it."""
    def write(self, path: _Path) -> int:
        """Write a .vxm file atomically; returns its length in bytes."""
    @property
    def voxel_size(self) -> float: ...
    @property
    def origin(self) -> Tuple[float, float, float]: ...
    @property
    def dims(self) -> Tuple[int, int, int]: ...
    @property
    def layers(self) -> int: ...
    @property
    def has_distances(self) -> bool: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def counts(self) -> dict[str, int]: ...
    @property
    def report(self) -> Optional[dict[str, Union[int, float, bool]]]: ...

class Pointshell:
    """One point per surface voxel with a unit normal pointing into the object."""

    @staticmethod
    def open(path: _Path) -> Pointshell: ...
    @property
    def points(self) -> npt.NDArray[np.float64]:
        """(N, 3) points in the object's frame, in sphere-tree order."""
    @property
    def normals(self) -> npt.NDArray[np.float64]:
        """(N, 3) unit normals pointing into the object."""
    @property
    def weights(self) -> npt.NDArray[np.float64]:
        """(N,) area each point stands for, in voxel faces, in [0, 1]: the weight of its push."""
    @property
    def voxel_size(self) -> float: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def stats(self) -> dict[str, int]: ...
    def write(self, path: _Path) -> int:
        """Write a .vps file atomically; returns its length in bytes."""
    def __len__(self) -> int: ...

class Contact:
    """Result of a contact query, in the voxmap's world frame."""

    force: Tuple[float, float, float]
    torque: Tuple[float, float, float]
    points_in_contact: int
    points_tested: int
    max_penetration: float
    deepest_point: Optional[int]
    """Index in the pointshell's `points` of a point `max_penetration` deep (of equals the
    lowest, in an exact query); None when no tested point has a positive penetration."""
    energy: float
    complete: bool
    force_error_bound: float
    micros: float
    def __iter__(self) -> Iterator[object]:
        """Unpacks as (force, torque, points_in_contact)."""

class SimulationStep:
    """What one step of a Simulation did, in the voxmap's world frame."""

    pose: Tuple[float, float, float, float, float, float, float]
    device_force: Tuple[float, float, float]
    device_torque: Tuple[float, float, float]
    contact_force: Tuple[float, float, float]
    points_in_contact: int
    max_penetration: float
    limited: bool
    out_of_time: bool
    queries: int
    kinetic_energy: float
    coupling_energy: float
    energy_gain: float
    energy_removed: float
    backed_off: bool
    micros: float

class Simulation:
    """The haptic loop: a simulated copy of the shell's object held through a virtual
    coupling, never passing through the voxmap's object (docs/HAPTICS.md)."""

    def __init__(
        self,
        voxmap: Voxmap,
        shell: Pointshell,
        start_pose: Sequence[float],
        *,
        mass: float = 1.0,
        inertia: Optional[Sequence[float]] = None,
        centre_of_mass: Optional[Sequence[float]] = None,
        coupling: Optional[Tuple[float, float]] = None,
        stiffness: Optional[float] = None,
        max_penetration: float = 0.25,
        penetration: Literal["distance", "layers", "sharp"] = "distance",
        budget_seconds: Optional[float] = None,
    ) -> None: ...
    def step(self, device_pose: Sequence[float]) -> SimulationStep:
        """One 1 ms step towards the device pose; render the returned device_force."""
    @property
    def pose(self) -> Tuple[float, float, float, float, float, float, float]: ...

def voxelize(
    mesh: Mesh,
    voxel_size: float,
    layers: int = 5,
    fill: Literal["winding", "objects", "scene"] = "winding",
    navigation: Literal["auto", "bbox", "zrange", "narrowing"] = "auto",
    distances: bool = False,
) -> Voxmap:
    """Voxelize a mesh into a voxmap in memory; with distances, each stored voxel's signed
    distance to the mesh too, which contact interpolates."""

def pointshell(
    mesh: Mesh,
    voxmap: Optional[Voxmap] = None,
    *,
    voxel_size: Optional[float] = None,
    layers: int = 5,
    leaf_size: int = ...,
) -> Pointshell:
    """The pointshell of a mesh, from its voxmap or from one made at voxel_size."""

def contact(
    voxmap: Voxmap,
    shell: Pointshell,
    pose: Optional[Sequence[float]] = None,
    *,
    stiffness: float = 1.0,
    budget_seconds: Optional[float] = None,
    penetration: Literal["distance", "layers", "sharp"] = "distance",
) -> Contact:
    """Force and torque of the voxmap on the shell at pose (tx, ty, tz[, qw, qx, qy, qz])."""
