"""Shared helpers: meshes made with numpy, OBJ writing, and the `vps` command line."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def sphere(center=(0.0, 0.0, 0.0), radius=1.0, rings=24, segments=48):
    """A closed UV sphere, outward-facing: vertices (V, 3) float64, triangles (T, 3) int64."""
    c = np.asarray(center, dtype=np.float64)
    theta = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    verts = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]]) * radius + c
    south = len(verts) - 1
    tris = []
    for j in range(segments):
        k = (j + 1) % segments
        tris.append((0, 1 + j, 1 + k))
        for i in range(rings - 2):
            a, b = 1 + i * segments + j, 1 + i * segments + k
            a2, b2 = a + segments, b + segments
            tris.append((a, a2, b2))
            tris.append((a, b2, b))
        last = 1 + (rings - 2) * segments
        tris.append((last + j, south, last + k))
    return verts, np.asarray(tris, dtype=np.int64)


def box(lo=(-1.0, -1.0, -1.0), hi=(1.0, 1.0, 1.0)):
    """A closed axis-aligned box, outward-facing."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64)
    verts = lo + corners * (hi - lo)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return verts, np.asarray(tris, dtype=np.int64)


def write_obj(path, verts, tris):
    """Write an OBJ whose numbers read back bit for bit."""
    with open(path, "w") as f:
        for v in verts:
            f.write("v {!r} {!r} {!r}\n".format(*map(float, v)))
        for t in tris:
            f.write("f {} {} {}\n".format(*(int(i) + 1 for i in t)))
    return Path(path)


def find_vps_bin():
    """The `vps` binary: $VPS_BIN, else the debug or release build in the target directory."""
    if os.environ.get("VPS_BIN"):
        return Path(os.environ["VPS_BIN"])
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("debug", "release"):
        exe = target / profile / "vps"
        if exe.exists():
            return exe
    return None


@pytest.fixture(scope="session")
def vps_bin():
    exe = find_vps_bin()
    if exe is None or not exe.exists():
        pytest.fail("no vps binary: build it with `cargo build -p vps-cli` or set VPS_BIN")
    return exe


@pytest.fixture(scope="session")
def run_vps(vps_bin):
    """Run the command line; returns the completed process (check=False)."""

    def run(*args, check=True):
        p = subprocess.run([str(vps_bin), *map(str, args)], capture_output=True, text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"vps {' '.join(map(str, args))} failed: {p.stderr}")
        return p

    return run
