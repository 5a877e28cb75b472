"""A `.vxm` reader written from `docs/FORMAT.md` alone, in plain Python: a second reading of
the spec, against which `test_format.py` checks the library's files and lookups.

Slow and obvious on purpose (voxel by voxel, the median by sorting, rANS one symbol at a
time), and it does not import `vps`. It reads versions 1 to 7 (the tests give it the two this
library writes, 1 and 7) and checks a file against the spec's rules: the header's fields and
limits, the layout and its zero padding, every CRC, the dictionary section (version 7: its
length, zstd dictionary and rANS tables), one zstd frame per payload of its codec's length
(codec 7: found by its block headers, then the distance stream, both its states ending
exactly where the encoder started them), the value range, the distances' range and sign,
sorted keys and runs, no stored brick in a run, and the header's counts against a recount of
the bricks.

Decoding every brick's distances voxel by voxel takes about 20 ms a brick here, so `read`
can be told which bricks to decode the distances of; every brick's values are decoded.
"""

import struct
import zlib
from dataclasses import dataclass, field

import zstandard

MAGIC = bytes([0x56, 0x58, 0x4D, 0x00, 0x0D, 0x0A, 0x1A, 0x0A])
ZSTD_MAGIC = bytes([0x28, 0xB5, 0x2F, 0xFD])
HEADER_BYTES = 192
VOXELS = 512
# Which codec each version's payloads use: the version's number.
CODECS = {1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 6: 6, 7: 7}
# The longest payload of each codec (`P`).
MAX_PAYLOAD = {1: 1024, 2: 2048, 3: 2048, 4: 2560, 5: 2560, 6: 2560, 7: 2560}
MAX_DICTIONARY_BYTES = 1 << 16
# Codec 7's rANS: 16 tables (contexts) of frequencies summing to 2^12, two states kept in
# [2^16, 2^32) by reading 16-bit words, and the escape symbol, followed by a raw word.
CONTEXTS, RANS_SLOTS, RANS_LOW, ESCAPE = 16, 1 << 12, 1 << 16, 255


class SpecError(Exception):
    """The file breaks a rule of docs/FORMAT.md."""


@dataclass
class VxmFile:
    version: int
    origin: tuple
    voxel_size: float
    dims: tuple
    layers: int
    counts: dict
    # key -> (512 values, 512 distances in steps of 1/32 voxel, or None)
    bricks: dict = field(default_factory=dict)
    # (start, end) brick keys of the inside runs
    runs: list = field(default_factory=list)

    @property
    def brick_dims(self):
        return tuple(d // 8 for d in self.dims)

    def key(self, b):
        """Brick key of brick coordinates b = (bx, by, bz): z fastest."""
        _, ny, nz = self.brick_dims
        return (b[0] * ny + b[1]) * nz + b[2]

    def voxel(self, v):
        """(value, distance in steps or None) of voxel v = (x, y, z); tiles have no distance."""
        b = tuple(c // 8 for c in v)
        k = self.key(b)
        local = (v[0] % 8) + 8 * (v[1] % 8) + 64 * (v[2] % 8)
        if k in self.bricks:
            values, distances = self.bricks[k]
            return values[local], None if distances is None else distances[local]
        inside = any(s <= k < e for s, e in self.runs)
        return (self.layers + 1 if inside else -(self.layers + 1)), None


def read(path, distances_of=None):
    """Read and check the whole file at `path`; the distances of the bricks whose keys are in
    `distances_of` only, if given (the others' are None)."""
    data = open(path, "rb").read()
    if data[:8] != MAGIC:
        raise SpecError("bad magic")
    u32 = lambda o: struct.unpack_from("<I", data, o)[0]  # noqa: E731
    u64 = lambda o: struct.unpack_from("<Q", data, o)[0]  # noqa: E731
    version = u32(8)
    if version not in CODECS or u32(12) != HEADER_BYTES:
        raise SpecError(f"version {version}, header of {u32(12)} bytes")
    if zlib.crc32(data[:188]) != u32(188):
        raise SpecError("header CRC")
    origin = struct.unpack_from("<3d", data, 16)
    voxel_size = struct.unpack_from("<d", data, 40)[0]
    dims = struct.unpack_from("<3I", data, 48)
    shift, edge, layers, codec = data[60], data[61], data[62], data[63]
    if (shift, edge) != (3, 8) or codec != CODECS[version] or layers > 126:
        raise SpecError(f"brick {shift}/{edge}, codec {codec}, layers {layers}")
    if any(d == 0 or d % 8 or d > 1 << 24 for d in dims) or not 0 < voxel_size < float("inf"):
        raise SpecError(f"grid {dims}, voxel size {voxel_size}")
    dictionary_bytes, dictionary_crc = u64(152), u32(184)
    if any(not abs(o) < float("inf") for o in origin) or any(data[160:184]):
        raise SpecError("origin not finite, or reserved bytes not zero")
    if version < 5 and (dictionary_bytes or dictionary_crc) or dictionary_bytes > MAX_DICTIONARY_BYTES:
        raise SpecError(f"a dictionary of {dictionary_bytes} bytes in version {version}")
    payload_offset = HEADER_BYTES + dictionary_bytes
    dictionary = data[HEADER_BYTES:payload_offset]
    if zlib.crc32(dictionary) != dictionary_crc:
        raise SpecError("dictionary CRC")
    # Version 7's section: the zstd dictionary's length and bytes, then the rANS tables.
    tables = None
    if version == 7:
        dictionary, tables = read_dictionary_section(dictionary)
    # zstd takes bytes without the dictionary magic as raw content, as this does. It must
    # load as a decompression dictionary, which a decompression makes it do (that of a frame
    # made without it): checked here, so that a file of no bricks is checked too.
    zdict = zstandard.ZstdCompressionDict(dictionary) if dictionary else None
    if zdict is not None:
        try:
            zstandard.ZstdDecompressor(dict_data=zdict).decompress(zstandard.ZstdCompressor().compress(b""))
        except zstandard.ZstdError as e:
            raise SpecError(f"zstd does not load the dictionary: {e}") from e
    names = ["surface_voxels", "inner_voxels", "bricks_stored", "inside_tile_bricks", "inside_runs",
             "payload_offset", "payload_bytes", "index_offset", "runs_offset", "file_bytes"]
    counts = {n: u64(64 + 8 * i) for i, n in enumerate(names)}
    counts["dictionary_bytes"] = dictionary_bytes
    # The layout follows from the counts.
    index_offset = (payload_offset + counts["payload_bytes"] + 7) // 8 * 8
    runs_offset = index_offset + 24 * counts["bricks_stored"]
    file_bytes = runs_offset + 16 * counts["inside_runs"]
    want = (payload_offset, index_offset, runs_offset, file_bytes, len(data))
    got = (counts["payload_offset"], counts["index_offset"], counts["runs_offset"], counts["file_bytes"], file_bytes)
    if want != got:
        raise SpecError(f"layout {got}, expected {want}")
    if zlib.crc32(data[index_offset:runs_offset]) != u32(144) or zlib.crc32(data[runs_offset:]) != u32(148):
        raise SpecError("index or run table CRC")
    if any(data[payload_offset + counts["payload_bytes"] : index_offset]):
        raise SpecError("padding before the index not zero")
    vxm = VxmFile(version, origin, voxel_size, dims, layers, counts)
    nb = vxm.brick_dims
    next_offset, last_key = payload_offset, -1
    for i in range(counts["bricks_stored"]):
        key, offset, length, crc = struct.unpack_from("<QQII", data, index_offset + 24 * i)
        if key <= last_key or key >= nb[0] * nb[1] * nb[2] or offset != next_offset:
            raise SpecError(f"index entry {i}: key {key}, offset {offset}")
        if not 1 <= length <= MAX_PAYLOAD[codec]:
            raise SpecError(f"index entry {i}: payload of {length} bytes")
        payload = data[offset : offset + length]
        if zlib.crc32(payload) != crc:
            raise SpecError(f"brick {key}: payload CRC")
        with_distances = distances_of is None or key in distances_of
        vxm.bricks[key] = decode_payload(payload, codec, layers, zdict, with_distances, tables)
        next_offset, last_key = offset + length, key
    if next_offset != payload_offset + counts["payload_bytes"]:
        raise SpecError("payloads do not tile their section")
    for i in range(counts["inside_runs"]):
        start, end = struct.unpack_from("<QQ", data, runs_offset + 16 * i)
        if not start < end <= nb[0] * nb[1] * nb[2] or (vxm.runs and start < vxm.runs[-1][1]):
            raise SpecError(f"run {i}: {start}..{end}")
        vxm.runs.append((start, end))
    if any(s <= k < e for k in vxm.bricks for s, e in vxm.runs):
        raise SpecError("a stored brick inside an inside run")
    # The header's counts, recounted.
    tiles = sum(e - s for s, e in vxm.runs)
    surface = sum(v == 0 for vs, _ in vxm.bricks.values() for v in vs)
    inner = sum(v > 0 for vs, _ in vxm.bricks.values() for v in vs) + VOXELS * tiles
    if (counts["inside_tile_bricks"], counts["surface_voxels"], counts["inner_voxels"]) != (tiles, surface, inner):
        raise SpecError(f"counts {counts}, recounted {tiles} tile bricks, {surface} surface, {inner} inner voxels")
    return vxm


def coords(i):
    return i % 8, (i // 8) % 8, i // 64


def previous_along(i):
    """The voxel before `i` in the predictor's order: along x, else y, else z; else None."""
    x, y, z = coords(i)
    return i - 1 if x > 0 else i - 8 if y > 0 else i - 64 if z > 0 else None


def wrap(v, bits):
    half = 1 << (bits - 1)
    return (v + half) % (1 << bits) - half


def unzigzag(z):
    return (z >> 1) ^ -(z & 1)


def read_dictionary_section(section):
    """Version 7's dictionary section: `u32 n`, `n` bytes of zstd dictionary, 16 rANS tables.
    Returns the zstd dictionary's bytes and, for each context, each slot's (symbol, f, c)."""
    at, tables = 0, []

    def take(size, what):
        nonlocal at
        if at + size > len(section):
            raise SpecError(f"dictionary section: {what} beyond the section's {len(section)} bytes")
        at += size
        return section[at - size : at]

    n = struct.unpack("<I", take(4, "the zstd dictionary's length"))[0]
    zstd_dictionary = take(n, f"a zstd dictionary of {n} bytes")
    for t in range(CONTEXTS):
        k = struct.unpack("<H", take(2, f"table {t}"))[0]
        if not 1 <= k <= 256:
            raise SpecError(f"rANS table {t}: {k} symbols")
        entries = [struct.unpack("<BH", take(3, f"table {t}")) for _ in range(k)]
        symbols, freqs = [s for s, _ in entries], [f for _, f in entries]
        if symbols != sorted(set(symbols)) or min(freqs) < 1 or sum(freqs) != RANS_SLOTS:
            raise SpecError(f"rANS table {t}: symbols not increasing, or frequencies not >= 1 summing to 4096")
        slots, c = [], 0
        for s, f in entries:
            slots += [(s, f, c)] * f  # symbol s holds the slots c(s) .. c(s) + f(s) - 1
            c += f
        tables.append(slots)
    if at != len(section):
        raise SpecError(f"dictionary section: {len(section) - at} bytes after the tables")
    return zstd_dictionary, tables


def frame_length(payload):
    """Where the zstd frame at the start of `payload` (magic removed) ends, by RFC 8878: the
    frame header, then blocks up to the last, then the checksum if the frame has one."""
    if not payload:
        raise SpecError("an empty payload")
    # The frame header descriptor's fields, then the window descriptor (unless the frame is
    # a single segment), the dictionary id and the content size, of the sizes they give.
    descriptor = payload[0]
    fcs_flag, single_segment, checksum = descriptor >> 6, descriptor >> 5 & 1, descriptor >> 2 & 1
    did_flag = descriptor & 3
    fcs_bytes = [1 if single_segment else 0, 2, 4, 8][fcs_flag]
    at = 1 + (0 if single_segment else 1) + [0, 1, 2, 4][did_flag] + fcs_bytes
    while True:
        if at + 3 > len(payload):
            raise SpecError("the zstd frame ends inside a block header")
        header = int.from_bytes(payload[at : at + 3], "little")
        last, kind, size = header & 1, header >> 1 & 3, header >> 3
        if kind == 3:
            raise SpecError("a zstd block of the reserved type")
        at += 3 + (1 if kind == 1 else size)  # an RLE block holds one byte
        if last:
            break
    at += 4 if checksum else 0
    if at > len(payload):
        raise SpecError("the zstd frame runs past the payload")
    return at


def decode_payload(payload, codec, layers, zdict=None, with_distances=True, tables=None):
    stream = b""
    if codec == 7:
        # The values' frame, then the distance stream to the end of the payload.
        end = frame_length(payload)
        payload, stream = payload[:end], payload[end:]
    frame = ZSTD_MAGIC + payload
    try:
        params = zstandard.get_frame_parameters(frame)
        if params.content_size == zstandard.CONTENTSIZE_UNKNOWN or params.dict_id != 0:
            raise SpecError("a frame without its content size, or with a dictionary id")
        # Exactly one frame: no bytes, and no second frame, after it (so zstd agrees with
        # `frame_length` on codec 7's). Codec 5's to 7's with the file's dictionary, if any.
        decompressor = zstandard.ZstdDecompressor(dict_data=zdict) if codec >= 5 and zdict else zstandard.ZstdDecompressor()
        raw = decompressor.decompress(frame, allow_extra_data=False)
    except zstandard.ZstdError as e:
        raise SpecError(f"not one zstd frame: {e}") from e
    lengths = {1: VOXELS, 2: 3 * VOXELS, 7: VOXELS}
    if len(raw) != lengths.get(codec, len(raw)) or not VOXELS <= len(raw) <= 2048:
        raise SpecError(f"codec {codec}: a frame of {len(raw)} bytes")
    values = [0] * VOXELS
    for i in range(VOXELS):
        p = previous_along(i)
        values[i] = wrap(raw[i] + (0 if p is None else values[p]), 8)
    if any(abs(v) > layers + 1 for v in values):
        raise SpecError("a value beyond the layers")
    if codec == 1 or not with_distances:
        return values, None
    stored = [v >= -1 for v in values]
    reach = (layers + 0.5) * 32
    if codec == 2:
        z = [raw[VOXELS + i] | raw[2 * VOXELS + i] << 8 for i in range(VOXELS)]
        d = [0] * VOXELS
        for i in range(VOXELS):
            p = previous_along(i)
            d[i] = wrap((0 if p is None else d[p]) + unzigzag(z[i]), 16)
        if any(abs(x) > reach for x in d):
            raise SpecError("a distance beyond the reach")
        # A reader puts the bound in place of the distances no contact reads.
        d = [d[i] if stored[i] else 32 * values[i] + 16 for i in range(VOXELS)]
    elif codec == 3:
        n = sum(stored)
        if len(raw) != VOXELS + 2 * n:
            raise SpecError("codec 3 payload length")
        d, k = [0] * VOXELS, 0
        for i in range(VOXELS):
            if not stored[i]:
                d[i] = 32 * values[i] + 16
                continue
            z = raw[VOXELS + k] | raw[VOXELS + n + k] << 8
            p = previous_along(i)
            d[i] = wrap((0 if p is None else d[p]) + unzigzag(z), 16)
            k += 1
    elif codec == 7:
        d = decode_diagonal(stream, values, stored, tables)
    else:
        d = decode_median(raw[VOXELS:], values, stored, codec)
    for i in range(VOXELS):
        if abs(d[i]) > reach:
            raise SpecError(f"voxel {i}: distance {d[i]} beyond the reach")
        if stored[i] and ((values[i] < 0 and d[i] >= 0) or (values[i] > 0 and d[i] <= 0)):
            raise SpecError(f"voxel {i}: distance {d[i]} on the wrong side of value {values[i]}")
    return values, d


def candidates(i, d, available):
    """Codec 4's nine candidates A to I of voxel `i` (None where one is not available), and its
    neighbours a, b, c: from the distances `d` of the voxels `available` marks."""
    x, y, z = coords(i)

    def n(dx, dy, dz):
        a, b, c = x + dx, y + dy, z + dz
        j = a + 8 * b + 64 * c
        return d[j] if 0 <= a < 8 and 0 <= b < 8 and 0 <= c < 8 and available[j] else None

    a, b, c = n(-1, 0, 0), n(0, -1, 0), n(0, 0, -1)
    a2, b2, c2 = n(-2, 0, 0), n(0, -2, 0), n(0, 0, -2)
    ab, ac, bc = n(-1, -1, 0), n(-1, 0, -1), n(0, -1, -1)
    xb, xc, yc = n(1, -1, 0), n(1, 0, -1), n(0, 1, -1)  # a⁺b, a⁺c, b⁺c

    def known(*vs):
        return all(v is not None for v in vs)

    return [
        a + b - ab if known(a, b, ab) else None,  # A
        a + c - ac if known(a, c, ac) else None,  # B
        b + c - bc if known(b, c, bc) else None,  # C
        2 * a - a2 if known(a, a2) else None,  # D
        2 * b - b2 if known(b, b2) else None,  # E
        2 * c - c2 if known(c, c2) else None,  # F
        xb + a - b if known(xb, a, b) else None,  # G
        xc + a - c if known(xc, a, c) else None,  # H
        yc + b - c if known(yc, b, c) else None,  # I
    ], (a, b, c)


def median_prediction(i, d, stored, values, codec):
    """Codec 4's (and 5's) prediction of voxel `i` from the distances `d` decoded before it
    (in index order every neighbour comes before), or codec 6's, from C, E, F and I only."""
    cands, (a, b, c) = candidates(i, d, stored)
    used = [cands[k] for k in (2, 4, 5, 8)] if codec == 6 else cands  # C, E, F, I
    available = sorted(v for v in used if v is not None)
    if available:
        return available[(len(available) - 1) // 2]
    if codec == 6 and cands[3] is not None:
        return cands[3]  # D = 2a - a2
    first = next((v for v in (a, b, c) if v is not None), None)
    return first if first is not None else 32 * values[i]


def decode_median(stream, values, stored, codec):
    d, at = [0] * VOXELS, 0
    for i in range(VOXELS):
        if not stored[i]:
            d[i] = 32 * values[i] + 16
            continue
        if at >= len(stream):
            raise SpecError("the residuals end before the stored distances")
        if stream[at] == 255:
            if at + 3 > len(stream):
                raise SpecError("the residuals end inside an escape")
            z, at = stream[at + 1] | stream[at + 2] << 8, at + 3
        else:
            z, at = stream[at], at + 1
        v = median_prediction(i, d, stored, values, codec) + unzigzag(z)
        if not -(1 << 15) <= v < (1 << 15):
            raise SpecError(f"voxel {i}: distance {v} beyond 16 bits")
        d[i] = v
    if at != len(stream):
        raise SpecError("residuals left over")
    return d


def diagonal_prediction(i, d, known, values):
    """Codec 7's prediction of voxel `i`: the median of candidates A to F."""
    cands, (a, b, c) = candidates(i, d, known)
    available = sorted(v for v in cands[:6] if v is not None)
    if not available:
        first = next((v for v in (a, b, c) if v is not None), None)
        return first if first is not None else 32 * values[i]
    return available[(len(available) - 1) // 2]


def residual_class(z):
    """Codec 7's class of the zigzagged residual z: 1 + m for a magnitude m below 4, else
    3 + floor(log2 m), at most 15."""
    m = (z + 1) >> 1
    return 1 + m if m < 4 else min(15, 3 + m.bit_length() - 1)


def diagonal_context(i, classes):
    """Codec 7's context of voxel `i`: the largest class among the residuals of its neighbours
    a, b, c, a⁺c and b⁺c that have one (`classes`, None where not), else 0."""
    x, y, z = coords(i)
    found = [0]
    for dx, dy, dz in ((-1, 0, 0), (0, -1, 0), (0, 0, -1), (1, 0, -1), (0, 1, -1)):
        a, b, c = x + dx, y + dy, z + dz
        if 0 <= a < 8 and 0 <= b < 8 and 0 <= c < 8 and classes[a + 8 * b + 64 * c] is not None:
            found.append(classes[a + 8 * b + 64 * c])
    return max(found)


def diagonal_order():
    """Codec 7's order: by x + y + 8z, then by x."""
    return sorted(range(512), key=lambda i: ((i & 7) + (i >> 3 & 7) + 8 * (i >> 6), i & 7))


def decode_diagonal(stream, values, stored, tables):
    """Codec 7's distances: a residual for each stored voxel in the diagonal order, residual j
    from rANS state x₀ for even j and x₁ for odd j, with its context's table; the two share
    the words, read in order (a renormalising word before an escape's)."""
    d = [32 * v + 16 for v in values]  # the bounds, for the voxels not stored
    if not any(stored):
        if stream:
            raise SpecError(f"a distance stream of {len(stream)} bytes for no stored distance")
        return d
    if len(stream) < 8 or len(stream) % 2:
        raise SpecError(f"a distance stream of {len(stream)} bytes")
    states = list(struct.unpack_from("<2I", stream))
    words = list(struct.unpack(f"<{(len(stream) - 8) // 2}H", stream[8:]))
    if min(states) < RANS_LOW:
        raise SpecError(f"initial rANS states {states}")
    at = 0
    # Available: stored and already decoded, so before in the order (every neighbour a
    # candidate names is; G's a⁺b would not be).
    known = [False] * VOXELS
    classes = [None] * VOXELS

    def word():
        nonlocal at
        if at == len(words):
            raise SpecError("the distance stream ends early")
        at += 1
        return words[at - 1]

    j = 0
    for i in diagonal_order():
        if not stored[i]:
            continue
        p = diagonal_prediction(i, d, known, values)
        context = diagonal_context(i, classes)
        x = states[j % 2]
        slot = x % RANS_SLOTS
        s, f, c = tables[context][slot]
        x = f * (x >> 12) + slot - c
        if x < RANS_LOW:
            x = x << 16 | word()
        states[j % 2], j = x, j + 1
        z = word() if s == ESCAPE else s
        d[i], known[i], classes[i] = wrap(p + unzigzag(z), 16), True, residual_class(z)
    if at != len(words) or states != [RANS_LOW, RANS_LOW]:
        left = len(words) - at
        raise SpecError(f"the distance stream ends with {left} words left and states {states}, not 65536")
    return d
