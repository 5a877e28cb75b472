#!/usr/bin/env python3
"""What the distances of a version 2 `.vxm` cost, and what other codings would make of them.

    python3 crates/vps/benches/distance_coding.py FILE.vxm [FILE.vxm ...]

Needs numpy and zstandard (`pip install numpy zstandard`; zstandard wraps the same zstd C
library the writer links). For each version 2 file (codec 2, `docs/FORMAT.md`) it decodes
every stored brick and prints, per brick:

- the payload bytes of the values alone and of values with distances, re-compressed as the
  writer does (zstd level 1, no checksum, content size, magic dropped);
- the same with a zstd dictionary trained on the file's own frames, and the time to
  decompress a frame with and without it (this process, best of three passes);
- the order-0 entropy of the distance residuals, bits a voxel, under the writer's predictor
  (the previous voxel) and a 3D Lorenzo predictor (the parallelepiped through the seven
  neighbours before a voxel; fewer on the brick's lower faces), at steps of 1/32 (stored),
  1/16 and 1/8 voxel.

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
    """The file's brick payloads as complete zstd frames (magic restored)."""
    data = open(path, "rb").read()
    version, codec = struct.unpack_from("<I", data, 8)[0], data[63]
    if version != 2 or codec != 2:
        raise SystemExit(f"{path}: version {version}, codec {codec}: this script reads version 2 files "
                         "(all distances stored); version 3 stores those of values -1 and above only")
    bricks, index_offset = struct.unpack_from("<Q", data, 80)[0], struct.unpack_from("<Q", data, 120)[0]
    out = []
    for b in range(bricks):
        _key, offset, length, _crc = struct.unpack_from("<QQII", data, index_offset + 24 * b)
        out.append(MAGIC + data[offset : offset + length])
    return out


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
        if i & 7:
            p = v[:, i - 1]
        elif i & 63:
            p = v[:, i - 8]
        elif i:
            p = v[:, i - 64]
        else:
            p = 0
        v[:, i] = p + residuals[:, i]
    return v


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


def report(path):
    frames = frames_of(path)
    raws = [zstd.ZstdDecompressor().decompress(f) for f in frames]
    n = len(raws)
    level1 = dict(level=1, write_checksum=False, write_content_size=True, write_dict_id=False)
    plain = zstd.ZstdCompressor(**level1)
    values_only = sum(len(plain.compress(r[:VOXELS])) - 4 for r in raws) / n
    with_distances = sum(len(f) - 4 for f in frames) / n
    print(f"{path}: {n} bricks; payload bytes a brick: values {values_only:.1f}, "
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

    raw = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(n, 3 * VOXELS).astype(np.int64)
    zigzag = raw[:, VOXELS : 2 * VOXELS] | (raw[:, 2 * VOXELS :] << 8)
    distances = undo_prediction((zigzag >> 1) ^ -(zigzag & 1)).reshape(n, 8, 8, 8)
    cells = []
    for q in (1, 2, 4):
        d = np.round(distances / q).astype(np.int64)
        cells.append(f"1/{32 // q}: previous voxel {entropy(d - previous_voxel(d)):.2f}, "
                     f"Lorenzo {entropy(d - lorenzo(d)):.2f}")
    print("  residual entropy, bits a voxel: " + "; ".join(cells))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    for p in sys.argv[1:]:
        report(p)
