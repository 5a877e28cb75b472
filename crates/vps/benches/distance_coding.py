#!/usr/bin/env python3
"""What the distances of a `.vxm` cost, and what other codings would make of them.

    python3 crates/vps/benches/distance_coding.py FILE.vxm [FILE.vxm ...]

Needs numpy and zstandard (`pip install numpy zstandard`; zstandard wraps the same zstd C
library the writer links). For each file with distances (version 2, codec 2, or version 3,
codec 3: `docs/FORMAT.md`) it decodes every stored brick and prints, per brick:

- the payload bytes of the values alone and of values with distances, re-compressed as the
  writer does (zstd level 1, no checksum, content size, magic dropped);
- the same with a zstd dictionary trained on the file's own frames, and the time to
  decompress a frame with and without it (this process, best of three passes);
- the order-0 entropy of the distance residuals, bits a voxel, under the writer's predictor
  (the previous voxel) and a 3D Lorenzo predictor (the parallelepiped through the seven
  neighbours before a voxel; fewer on the brick's lower faces), at steps of 1/32 (stored),
  1/16 and 1/8 voxel, over the distances version 3 stores (values -1 and above);
- what an ideal coder with context would need (`context_bounds`): the file's own conditional
  entropies, with no cost for its tables, so a bound no real coder reaches.

A scratch measurement for `docs/PERFORMANCE.md`, not a test: nothing here is asserted.
"""

import random
import struct
import sys
import time

import numpy as np
import zstandard as zstd

MAGIC = b"\x28\xb5\x2f\xfd"
VOXELS = 512


def frames_of(path):
    """The file's codec and its brick payloads as complete zstd frames (magic restored)."""
    data = open(path, "rb").read()
    version, codec = struct.unpack_from("<I", data, 8)[0], data[63]
    if (version, codec) not in ((2, 2), (3, 3)):
        raise SystemExit(f"{path}: version {version}, codec {codec}: this script reads the files "
                         "with distances (version 2, codec 2; version 3, codec 3)")
    bricks, index_offset = struct.unpack_from("<Q", data, 80)[0], struct.unpack_from("<Q", data, 120)[0]
    out = []
    for b in range(bricks):
        _key, offset, length, _crc = struct.unpack_from("<QQII", data, index_offset + 24 * b)
        out.append(MAGIC + data[offset : offset + length])
    return codec, out


def decode(codec, raws):
    """Values and distances (steps of 1/32 voxel) of every brick, bricks × 512 each, with
    the distances codec 3 leaves out (values -2 and below) at their bound, `32·v + 16`."""
    n = len(raws)
    values = np.zeros((n, VOXELS), dtype=np.int64)
    residuals = np.zeros((n, VOXELS), dtype=np.int64)
    for b, r in enumerate(raws):
        values[b] = np.frombuffer(r[:VOXELS], dtype=np.int8)
    values = ((undo_prediction(values) + 128) % 256) - 128
    stored = values >= -1
    for b, r in enumerate(raws):
        m = int(stored[b].sum()) if codec == 3 else VOXELS
        low = np.frombuffer(r[VOXELS : VOXELS + m], dtype=np.uint8).astype(np.int64)
        high = np.frombuffer(r[VOXELS + m : VOXELS + 2 * m], dtype=np.uint8).astype(np.int64)
        z = low | (high << 8)
        unzigzagged = (z >> 1) ^ -(z & 1)
        if codec == 3:
            residuals[b][stored[b]] = unzigzagged
        else:
            residuals[b] = unzigzagged
    bound = 32 * values + 16
    # What each voxel predicts the next with: codec 2 chains every stored distance, codec 3
    # puts the bound in place of those it leaves out.
    chain = np.zeros_like(residuals)
    for i in range(VOXELS):
        d = ((prediction(chain, i) + residuals[:, i] + 32768) % 65536) - 32768
        chain[:, i] = np.where(stored[:, i], d, bound[:, i]) if codec == 3 else d
    return values, np.where(stored, chain, bound)


def previous_voxel(a):
    """The writer's prediction of every entry: the voxel before along x, else y, else z."""
    p = np.zeros_like(a)
    p[:, 1:, :, :] = a[:, :-1, :, :]  # first of a slice: the one below in z
    p[:, :, 1:, :] = a[:, :, :-1, :]  # first of a row: the one below in y
    p[:, :, :, 1:] = a[:, :, :, :-1]
    return p


def undo_prediction(residuals):
    """Running sums in index order (bricks × 512, z-major)."""
    v = np.zeros_like(residuals)
    for i in range(VOXELS):
        v[:, i] = prediction(v, i) + residuals[:, i]
    return v


def prediction(decoded, i):
    """The writer's prediction of entry `i` of every brick from the entries decoded before it:
    the one before along x, else y, else z, else 0."""
    if i & 7:
        return decoded[:, i - 1]
    if i & 63:
        return decoded[:, i - 8]
    if i:
        return decoded[:, i - 64]
    return 0


def lorenzo(d):
    """3D Lorenzo prediction, the terms of a missing neighbour dropped."""
    pad = np.pad(d, ((0, 0), (1, 0), (1, 0), (1, 0)))
    z, y, x = np.meshgrid(np.arange(8), np.arange(8), np.arange(8), indexing="ij")
    hx, hy, hz = x > 0, y > 0, z > 0

    def at(dz, dy, dx):
        return pad[:, 1 - dz : 9 - dz, 1 - dy : 9 - dy, 1 - dx : 9 - dx]

    return (
        at(0, 0, 1) * hx + at(0, 1, 0) * hy + at(1, 0, 0) * hz
        - at(0, 1, 1) * (hx & hy) - at(1, 0, 1) * (hx & hz) - at(1, 1, 0) * (hy & hz)
        + at(1, 1, 1) * (hx & hy & hz)
    )


def entropy(r):
    _, counts = np.unique(r, return_counts=True)
    p = counts / counts.sum()
    return float(-(p * np.log2(p)).sum())


def decode_us(frames, dictionary=None):
    d = zstd.ZstdDecompressor(dict_data=dictionary) if dictionary else zstd.ZstdDecompressor()
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        for f in frames:
            d.decompress(f)
        best = min(best, (time.perf_counter() - start) / len(frames))
    return best * 1e6


def conditional_bits(symbols, context):
    """Bits to code `symbols` with the file's own frequencies of each symbol in each context:
    the conditional entropy times the count, tables free."""
    pairs = np.stack([context.ravel(), symbols.ravel()], axis=1)
    _, pair_of, pair_counts = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    _, context_of, context_counts = np.unique(context.ravel(), return_inverse=True, return_counts=True)
    return float(-np.log2(pair_counts[pair_of.ravel()] / context_counts[context_of.ravel()]).sum())


def before(a, dz, dy, dx, outside):
    """Each voxel's neighbour `(dz, dy, dx)` voxels before it in its brick, `outside` where
    that leaves the brick."""
    pad = np.pad(a, ((0, 0), (1, 0), (1, 0), (1, 0)), constant_values=outside)
    return pad[:, 1 - dz : 9 - dz, 1 - dy : 9 - dy, 1 - dx : 9 - dx]


def context_bounds(values, distances):
    """Bytes a brick an ideal coder with context would need, each brick on its own, in an
    order a decoder can follow (contexts from what is already decoded: the voxels before a
    voxel in index order, and the values before the distances):
    - the values: each given the values before it along x, y and z;
    - then the distances of the voxels stored (values -1 and above, known by then): the
      Lorenzo residual given the voxel's value (-1 to 3) and the size of the residuals before
      it along x, y and z."""
    v = values.reshape(-1, 8, 8, 8)
    d = distances.reshape(-1, 8, 8, 8)
    stored = v >= -1
    n = len(v)
    vx, vy, vz = before(v, 0, 0, 1, 99), before(v, 0, 1, 0, 99), before(v, 1, 0, 0, 99)
    values_alone = conditional_bits(v, ((vx + 128) * 256 + vy + 128) * 256 + vz + 128)
    r = d - lorenzo(d)
    size = sum(np.abs(before(r, *o, 0)) for o in ((0, 0, 1), (0, 1, 0), (1, 0, 0)))
    size_class = np.searchsorted(np.array([1, 2, 3, 5, 8, 12, 20, 40]), size, side="right")
    distance_bits = conditional_bits(r[stored], (np.clip(v, -1, 3) * 16 + size_class)[stored])
    return values_alone / 8 / n, (values_alone + distance_bits) / 8 / n


def report(path):
    codec, frames = frames_of(path)
    raws = [zstd.ZstdDecompressor().decompress(f) for f in frames]
    n = len(raws)
    level1 = dict(level=1, write_checksum=False, write_content_size=True, write_dict_id=False)
    plain = zstd.ZstdCompressor(**level1)
    values_only = sum(len(plain.compress(r[:VOXELS])) - 4 for r in raws) / n
    with_distances = sum(len(f) - 4 for f in frames) / n
    print(f"{path}: codec {codec}, {n} bricks; payload bytes a brick: values {values_only:.1f}, "
          f"with distances {with_distances:.1f} (+{with_distances - values_only:.1f})")

    sample = random.Random(1).sample(raws, min(4000, n))
    dictionary = zstd.train_dictionary(4096, sample, level=1)
    dict_frames = [zstd.ZstdCompressor(dict_data=dictionary, **level1).compress(r) for r in raws]
    v1_raws = [r[:VOXELS] for r in raws]
    v1_dictionary = zstd.train_dictionary(4096, random.Random(1).sample(v1_raws, min(4000, n)), level=1)
    v1_dict = sum(len(zstd.ZstdCompressor(dict_data=v1_dictionary, **level1).compress(r)) - 4 for r in v1_raws) / n
    timed = frames[:20000]
    print(f"  with a 4 KiB dictionary: values {v1_dict:.1f}, with distances "
          f"{sum(len(f) - 4 for f in dict_frames) / n:.1f}; decoding a frame "
          f"{decode_us(timed):.2f} µs, with the dictionary {decode_us(dict_frames[:20000], dictionary):.2f} µs")

    values, distances = decode(codec, raws)
    stored = (values >= -1).reshape(n, 8, 8, 8)
    distances = distances.reshape(n, 8, 8, 8)
    cells = []
    for q in (1, 2, 4):
        d = np.round(distances / q).astype(np.int64)
        cells.append(f"1/{32 // q}: previous voxel {entropy((d - previous_voxel(d))[stored]):.2f}, "
                     f"Lorenzo {entropy((d - lorenzo(d))[stored]):.2f}")
    print(f"  residual entropy, bits a stored voxel ({stored.sum() / n:.0f} a brick): " + "; ".join(cells))

    alone, joint = context_bounds(values, distances)
    index = 24  # an index entry a brick, in either file
    print(f"  an ideal coder with context, bytes a brick: values {alone:.1f}, values with distances "
          f"{joint:.1f}; with the index entry, against values alone as written: "
          f"{(joint + index) / (values_only + index):.3f}, as it would code them: {(joint + index) / (alone + index):.3f} "
          f"(as written now: {(with_distances + index) / (values_only + index):.3f})")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    for p in sys.argv[1:]:
        report(p)
