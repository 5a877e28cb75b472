"""Files the library writes, read by `vxm_spec.py` (a reader written from docs/FORMAT.md alone),
against the library's own lookups and against distances computed here from the triangles."""

import struct
import zlib

import numpy as np
import pytest

import vps
from conftest import box, sphere
from vxm_spec import VOXELS, SpecError, read

SIZE = 0.25
LAYERS = 2


def ball():
    # Off the voxel lattice, so that no facet lies on a voxel face by accident, and around
    # a brick's centre, so that one brick is an inside tile.
    return sphere(center=(1.11, 0.77, 1.07), radius=3.6, rings=10, segments=20)


def cracked_soup():
    """A box and a ball overlapping, as CAD exports them: a facet of each missing (cracks),
    a few flipped, one duplicated."""
    bv, bt = box((-1.5, -1.0, -0.8), (0.4, 1.1, 0.9))
    sv, st = sphere(center=(0.7, 0.1, 0.2), radius=1.0, rings=8, segments=16)
    verts = np.vstack([bv, sv])
    tris = np.vstack([bt[1:], st[3:] + len(bv), st[10:11] + len(bv)])
    tris[[2, 7, 20, 33]] = tris[[2, 7, 20, 33]][:, ::-1]
    return verts, tris


def centres(vxm, voxels):
    """World centres of grid voxels (N, 3)."""
    return np.asarray(vxm.origin) + (np.asarray(voxels, dtype=np.float64) + 0.5) * vxm.voxel_size


def brick_voxels(vxm, key):
    """The 512 grid voxels of brick `key`, in local index order."""
    _, ny, nz = vxm.brick_dims
    b = np.array([key // (ny * nz), key // nz % ny, key % nz])
    i = np.arange(VOXELS)
    return b * 8 + np.stack([i % 8, i // 8 % 8, i // 64], axis=1)


@pytest.mark.parametrize("mesh", [ball, cracked_soup], ids=["ball", "cracked soup"])
def test_the_spec_reads_the_values_and_distances_the_library_looks_up(mesh, tmp_path):
    made = vps.voxelize(vps.Mesh(*mesh()), SIZE, layers=LAYERS, distances=True)
    path = tmp_path / "part.vxm"
    made.write(path)
    vxm = read(path)
    assert vxm.version == 7 and vxm.layers == LAYERS and vxm.voxel_size == SIZE
    assert vxm.counts["bricks_stored"] == len(vxm.bricks) > 0
    # Every voxel of every stored brick, and a voxel of each tile brick: tiles have no
    # stored distance and read as the reach, with the tile's sign.
    voxels, values, steps = [], [], []
    for key, (vs, ds) in vxm.bricks.items():
        voxels.append(brick_voxels(vxm, key))
        values += vs
        steps += ds
    nx, ny, nz = vxm.brick_dims
    tiles = [k for k in range(nx * ny * nz) if k not in vxm.bricks]
    reach = (LAYERS + 0.5) * 32
    for k in tiles:
        voxels.append(brick_voxels(vxm, k)[[137]])
        value = vxm.voxel(tuple(voxels[-1][0]))[0]
        values.append(value)
        steps.append(reach if value > 0 else -reach)
    if mesh is ball:
        assert any(v > 0 for v in values[-len(tiles) :]), "an inside tile"
    points = centres(vxm, np.vstack(voxels))
    for voxmap in (made, vps.Voxmap.open(path)):
        assert voxmap.has_distances
        assert np.array_equal(voxmap.values(points), np.array(values, dtype=np.int8))
        # At a voxel centre the blend is that voxel's distance alone; these centres and
        # sizes are exact in binary, so the same bits.
        assert np.array_equal(voxmap.distances(points), np.array(steps) / 32 * SIZE)


def test_a_large_part_reads_by_the_spec_through_its_dictionary(tmp_path):
    """A part of some thousand bricks gets a zstd dictionary (codec 7): the spec reads every
    brick's values through it, and the distances of a sample of bricks through the rANS
    tables, as the library looks them up."""
    made = vps.voxelize(vps.Mesh(*sphere(center=(0.31, 0.17, 0.23), radius=15.0, rings=48, segments=96)), SIZE,
                        layers=LAYERS, distances=True)
    path = tmp_path / "large.vxm"
    made.write(path)
    keys = sorted(read(path, distances_of=set()).bricks)
    sample = set(keys[:8] + keys[len(keys) // 2 : len(keys) // 2 + 8] + keys[-8:])
    vxm = read(path, distances_of=sample)
    # Version 7's dictionary section is never empty (it holds the tables): its first u32 is
    # the zstd dictionary's length.
    zstd_bytes = struct.unpack_from("<I", path.read_bytes(), 192)[0]
    assert vxm.version == 7 and len(keys) > 1000 and zstd_bytes > 0, (zstd_bytes, vxm.counts)
    voxels = np.vstack([brick_voxels(vxm, k) for k in sorted(sample)])
    values = [v for k in sorted(sample) for v in vxm.bricks[k][0]]
    steps = [d for k in sorted(sample) for d in vxm.bricks[k][1]]
    points = centres(vxm, voxels)
    voxmap = vps.Voxmap.open(path)
    assert np.array_equal(voxmap.values(points), np.array(values, dtype=np.int8))
    assert np.array_equal(voxmap.distances(points), np.array(steps) / 32 * SIZE)


def test_a_dictionary_zstd_does_not_load_is_refused_at_open(tmp_path):
    """A zstd dictionary with its magic and id but entropy tables zstd cannot read, the
    section's CRC and the header's made right again: the spec refuses the file before it
    reads a brick, and so does the library. In version 7 the zstd dictionary starts at 196,
    after its length (a u32), and the rANS tables follow it in the same section."""
    made = vps.voxelize(vps.Mesh(*sphere(center=(0.31, 0.17, 0.23), radius=15.0, rings=48, segments=96)), SIZE,
                        layers=LAYERS, distances=True)
    path = tmp_path / "large.vxm"
    made.write(path)
    data = bytearray(path.read_bytes())
    size = struct.unpack_from("<Q", data, 152)[0]
    assert struct.unpack_from("<I", data, 192)[0] > 64 and data[196:200] == bytes.fromhex("37a430ec")
    data[204:236] = b"\xff" * 32
    struct.pack_into("<I", data, 184, zlib.crc32(data[192:192 + size]))
    struct.pack_into("<I", data, 188, zlib.crc32(data[:188]))
    broken = tmp_path / "broken.vxm"
    broken.write_bytes(bytes(data))
    with pytest.raises(SpecError, match="does not load the dictionary"):
        read(broken, distances_of=set())
    with pytest.raises(Exception, match="dictionary"):
        vps.Voxmap.open(broken)


def test_a_voxmap_without_distances_reads_by_the_spec_as_version_1(tmp_path):
    made = vps.voxelize(vps.Mesh(*cracked_soup()), SIZE, layers=LAYERS)
    path = tmp_path / "part.vxm"
    made.write(path)
    vxm = read(path)
    assert vxm.version == 1 and all(ds is None for _, ds in vxm.bricks.values())
    voxels = np.vstack([brick_voxels(vxm, k) for k in vxm.bricks])
    values = [v for vs, _ in vxm.bricks.values() for v in vs]
    for voxmap in (made, vps.Voxmap.open(path)):
        assert not voxmap.has_distances
        assert np.array_equal(voxmap.values(centres(vxm, voxels)), np.array(values, dtype=np.int8))
        with pytest.raises(ValueError, match="no distances"):
            voxmap.distances([[0.0, 0.0, 0.0]])


def test_distances_beyond_the_grid_or_not_finite_are_minus_the_reach():
    voxmap = vps.voxelize(vps.Mesh(*ball()), SIZE, layers=LAYERS, distances=True)
    far = [[1e9, 0.0, 0.0], [np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [0.0, 0.0, -np.inf]]
    assert np.array_equal(voxmap.distances(far), np.full(4, -(LAYERS + 0.5) * SIZE))
    with pytest.raises(ValueError):
        voxmap.distances([[0.0, 0.0]])


def closest_distances(points, verts, tris):
    """Unsigned distance from each point to the nearest triangle: every point against every
    triangle (the regions of the closest point, as in Ericson's Real-Time Collision Detection)."""
    best = np.full(len(points), np.inf)
    for a, b, c in verts[tris]:
        ab, ac, ap = b - a, c - a, points - a
        d1, d2 = ap @ ab, ap @ ac
        bp = points - b
        d3, d4 = bp @ ab, bp @ ac
        cp = points - c
        d5, d6 = cp @ ab, cp @ ac
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        with np.errstate(divide="ignore", invalid="ignore"):
            denom = va + vb + vc
            v, w = vb / denom, vc / denom
            face = a + v[:, None] * ab + w[:, None] * ac
            t_ab = d1 / (d1 - d3)
            t_ac = d2 / (d2 - d6)
            t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        q = face
        q = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[:, None], b + t_bc[:, None] * (c - b), q)
        q = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[:, None], a + t_ac[:, None] * ac, q)
        q = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[:, None], a + t_ab[:, None] * ab, q)
        q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
        q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
        q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
        best = np.minimum(best, np.linalg.norm(points - q, axis=1))
    return best


def test_the_stored_distances_are_those_of_the_triangles(tmp_path):
    """Each distance the file stores is its voxel centre's distance to the mesh, rounded to
    1/32 voxel, positive inside, within the reach of (layers + ½) voxels: checked against a
    brute force over every triangle, and the inside of this convex ball from its facets'
    planes."""
    verts, tris = ball()
    path = tmp_path / "ball.vxm"
    vps.voxelize(vps.Mesh(verts, tris), SIZE, layers=LAYERS, distances=True).write(path)
    vxm = read(path)
    voxels, values, steps = [], [], []
    for key, (vs, ds) in vxm.bricks.items():
        keep = np.array(vs) >= -1  # the distances a contact reads, and the file stores
        voxels.append(brick_voxels(vxm, key)[keep])
        values.append(np.array(vs)[keep])
        steps.append(np.array(ds)[keep])
    points = centres(vxm, np.vstack(voxels))
    values, stored = np.concatenate(values), np.concatenate(steps) / 32 * SIZE
    tri = verts[tris]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inside = np.all(np.einsum("pj,tj->pt", points, normals) <= np.einsum("tj,tj->t", tri[:, 0], normals), axis=1)
    reach = (LAYERS + 0.5) * SIZE
    exact = np.clip(np.where(inside, 1.0, -1.0) * closest_distances(points, verts, tris), -reach, reach)
    assert len(points) > 1000 and (values > 0).any() and (values == -1).any()
    assert np.abs(stored - exact).max() <= SIZE / 64 + 1e-12
    assert np.all(np.sign(stored[values != 0]) == np.sign(values[values != 0]))
