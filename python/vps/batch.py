"""Batch generation on a Dask cluster: many parts, each at several voxel sizes.

One task per (part, voxel size): load the mesh, voxelize, write ``<name>@<size>.vxm`` and,
unless told not to, the pointshell ``<name>@<size>.vps``, into a shared output directory.
Files are written atomically (a temporary file beside the target, renamed over it), so a
reader sees a whole file or none, and a task that is run again (a retry, a rerun of the
batch) replaces its files whole. A part that fails is reported in its record, with the
library's message; the other tasks go on. The records are also written, atomically, to
``batch.json`` in the output directory.

From Python::

    from dask.distributed import Client
    from vps.batch import run_batch

    client = Client("tcp://scheduler:8786")          # or None: a local cluster
    records = run_batch(parts, [2.0, 1.0], "/shared/voxmaps", client=client)

From the shell::

    python -m vps.batch parts/*.obj --sizes 2,1 --out /shared/voxmaps [--scheduler ADDR]

See docs/PYTHON.md, which also says when one machine's out-of-core path is the better tool.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Union

PathLike = Union[str, "os.PathLike[str]"]

#: The summary file written in the output directory.
SUMMARY = "batch.json"
# Extensions dropped from a part's file name to name its outputs.
MESH_EXTENSIONS = ("obj", "stl", "ply", "gltf", "glb", "toml")


def size_label(voxel_size: float) -> str:
    """The voxel size as it appears in file names: ``2``, ``0.5``, ``1e-05``."""
    return format(float(voxel_size), "g")


def part_names(parts: Sequence[PathLike]) -> List[str]:
    """A file-name stem for each part, unique within the batch.

    The stem of the file (``door.obj``, ``door.obj.zst``, ``door.stl`` and ``door.toml`` give
    ``door``); two parts with
    the same stem in different directories get a short hash of their path appended, so no
    two tasks write the same file.
    """
    stems = []
    for p in parts:
        name = Path(p).name
        if name.lower().endswith(".zst"):
            name = name[: -len(".zst")]
        stem, dot, ext = name.rpartition(".")
        if dot and ext.lower() in MESH_EXTENSIONS:
            name = stem
        stems.append(name)
    names = []
    for p, stem in zip(parts, stems):
        if stems.count(stem) > 1:
            digest = hashlib.sha1(os.path.abspath(os.fspath(p)).encode()).hexdigest()[:8]
            stem = f"{stem}-{digest}"
        names.append(stem)
    return names


def run_task(
    part: str,
    name: str,
    voxel_size: float,
    out_dir: str,
    layers: int = 5,
    pointshell: bool = True,
) -> Dict[str, Any]:
    """One task: voxelize ``part`` at ``voxel_size`` and write its files.

    Never raises: a failure is returned as a record with ``ok`` false and the error's type
    and message.
    """
    import vps

    stem = f"{name}@{size_label(voxel_size)}"
    record: Dict[str, Any] = {
        "part": part,
        "name": name,
        "voxel_size": voxel_size,
        "ok": False,
        "error": None,
        "error_type": None,
        "voxmap": None,
        "pointshell": None,
        "seconds": 0.0,
    }
    start = time.perf_counter()
    try:
        mesh = vps.Mesh.load(part)
        voxmap = vps.voxelize(mesh, voxel_size, layers=layers)
        vxm = os.path.join(out_dir, stem + ".vxm")
        record["voxmap_bytes"] = voxmap.write(vxm)
        record["voxmap"] = vxm
        record["triangles"] = mesh.triangle_count
        record["dims"] = list(voxmap.dims)
        record.update(voxmap.counts)
        if pointshell:
            shell = vps.pointshell(mesh, voxmap)
            vps_path = os.path.join(out_dir, stem + ".vps")
            record["pointshell_bytes"] = shell.write(vps_path)
            record["pointshell"] = vps_path
            record["points"] = len(shell)
        record["ok"] = True
    except Exception as e:  # noqa: BLE001 - every failure is reported, none stops the batch
        record["error"] = str(e)
        record["error_type"] = type(e).__name__
    record["seconds"] = time.perf_counter() - start
    return record


def write_json_atomically(path: PathLike, value: Any) -> None:
    """Write ``value`` as JSON to ``path`` through a temporary file renamed over it."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(value, f, indent=1)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def run_batch(
    parts: Sequence[PathLike],
    voxel_sizes: Sequence[float],
    out_dir: PathLike,
    client: Optional[Any] = None,
    layers: int = 5,
    pointshell: bool = True,
) -> List[Dict[str, Any]]:
    """Run one Dask task per (part, voxel size) and return their records, in that order.

    ``client`` is a ``dask.distributed.Client``; ``None`` starts a local cluster for the
    batch (one single-threaded worker process per core) and closes it after. ``out_dir``
    must be a directory every worker can write (created if missing). Each record holds the
    part, its name, the voxel size, ``ok``, ``error`` and ``error_type`` (``None`` when
    ok), ``seconds``, the files written and their counts. A task whose worker died is
    reported as failed too. The records are also written to ``out_dir/batch.json``.
    """
    from dask.distributed import Client, LocalCluster

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    parts = [os.path.abspath(os.fspath(p)) for p in parts]
    names = part_names(parts)
    jobs = [(p, n, float(s)) for p, n in zip(parts, names) for s in voxel_sizes]

    own = None
    if client is None:
        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1, processes=True)
        own = client = Client(cluster)
    try:
        futures = [
            client.submit(
                run_task,
                part,
                name,
                size,
                os.path.abspath(out),
                layers,
                pointshell,
                key=f"vps-{name}@{size_label(size)}-{i}",
                pure=False,
            )
            for i, (part, name, size) in enumerate(jobs)
        ]
        records = []
        for (part, name, size), future in zip(jobs, futures):
            try:
                records.append(future.result())
            except Exception as e:  # noqa: BLE001 - the worker died or the task was lost
                records.append(
                    {
                        "part": part,
                        "name": name,
                        "voxel_size": size,
                        "ok": False,
                        "error": str(e) or repr(e),
                        "error_type": type(e).__name__,
                        "voxmap": None,
                        "pointshell": None,
                        "seconds": 0.0,
                    }
                )
    finally:
        if own is not None:
            cluster = own.cluster
            own.close()
            cluster.close()
    write_json_atomically(out / SUMMARY, records)
    return records


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m vps.batch``: exit status 0 when every task succeeded, 1 otherwise."""
    ap = argparse.ArgumentParser(
        prog="python -m vps.batch",
        description="Voxelize many parts at several voxel sizes on a Dask cluster, one task each.",
    )
    ap.add_argument("parts", nargs="+", help="mesh files (.obj, .obj.zst, .stl, .ply, .gltf, .glb) or scene files (.toml)")
    ap.add_argument("--sizes", required=True, help="voxel sizes, comma-separated, e.g. 2,1,0.5")
    ap.add_argument("--out", required=True, help="output directory, shared by all workers")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler (default: a local cluster)")
    ap.add_argument("--layers", type=int, default=5, help="layers on each side of the surface (default 5)")
    ap.add_argument("--no-pointshell", action="store_true", help="write only the voxmaps")
    args = ap.parse_args(argv)
    try:
        sizes = [float(s) for s in args.sizes.split(",") if s.strip()]
    except ValueError:
        ap.error(f"--sizes must be numbers separated by commas, got {args.sizes!r}")
    client = None
    if args.scheduler:
        from dask.distributed import Client

        client = Client(args.scheduler)
    try:
        records = run_batch(
            args.parts, sizes, args.out, client=client, layers=args.layers, pointshell=not args.no_pointshell
        )
    finally:
        if client is not None:
            client.close()
    failed = [r for r in records if not r["ok"]]
    for r in records:
        status = "ok    " if r["ok"] else "FAILED"
        detail = r["voxmap"] if r["ok"] else f"{r['error_type']}: {r['error']}"
        print(f"{status} {r['name']}@{size_label(r['voxel_size'])} {r['seconds']:.2f} s  {detail}")
    print(f"{len(records) - len(failed)} of {len(records)} tasks succeeded; summary in {Path(args.out) / SUMMARY}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
