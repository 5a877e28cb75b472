"""Python against Rust on one large voxelization (not a test: a measurement for
docs/PERFORMANCE.md).

    python python/bench/speed.py [--voxels 1e8] [--repeat 3] [--vps target/release/vps]

Writes a sphere (as an OBJ) sized so that its grid has about --voxels voxels, then times
`vps voxelize --json` (its own "seconds": voxelize and write, the mesh already read) and
the same work from Python (`vps.voxelize` and `Voxmap.write` on a mesh loaded with
`vps.Mesh.load`), alternately, and prints the medians and the overhead of Python.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import vps  # noqa: E402
from conftest import sphere, write_obj  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--voxels", type=float, default=1e8, help="grid voxels to aim at (default 1e8)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--vps", default=os.environ.get("VPS_BIN", "target/release/vps"), help="the vps binary")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        obj = write_obj(Path(d) / "sphere.obj", *sphere(radius=1.0, rings=256, segments=512))
        size = 2.0 / (args.voxels ** (1 / 3))
        mesh = vps.Mesh.load(obj)
        rust, python = [], []
        for _ in range(args.repeat):
            out = subprocess.run(
                [args.vps, "voxelize", str(obj), "--voxel-size", repr(size), "-o", f"{d}/rust.vxm", "--json"],
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            rust.append(json.loads(out)["seconds"])
            start = time.perf_counter()
            vm = vps.voxelize(mesh, size)
            vm.write(f"{d}/python.vxm")
            python.append(time.perf_counter() - start)
            del vm
        dims = vps.Voxmap.open(f"{d}/python.vxm").dims
        same = Path(f"{d}/rust.vxm").read_bytes() == Path(f"{d}/python.vxm").read_bytes()
    r, p = statistics.median(rust), statistics.median(python)
    print(f"grid {dims[0]}x{dims[1]}x{dims[2]} = {dims[0] * dims[1] * dims[2]:.3e} voxels, voxel size {size:.5g}")
    print(f"rust   {r:.3f} s (median of {args.repeat}: {', '.join(f'{t:.3f}' for t in rust)})")
    print(f"python {p:.3f} s (median of {args.repeat}: {', '.join(f'{t:.3f}' for t in python)})")
    print(f"python overhead {100 * (p - r) / r:+.1f} %; files identical: {same}")


if __name__ == "__main__":
    main()
