"""The cluster batch on a local Dask cluster of two worker processes."""

import json
import os

import pytest

import vps
from conftest import box, sphere, write_obj
from vps.batch import SUMMARY, main, part_names, run_batch

distributed = pytest.importorskip("dask.distributed")

SIZES = [0.5, 0.25]


@pytest.fixture
def parts(tmp_path):
    d = tmp_path / "parts"
    d.mkdir()
    ball = write_obj(d / "ball.obj", *sphere(radius=1.0, rings=12, segments=24))
    brick = write_obj(d / "brick.obj", *box((0, 0, 0), (2.0, 1.0, 0.5)))
    broken = d / "broken.obj"
    broken.write_text("v 0 0 0\nf 1 2 3\n")  # refers to vertices that are not there
    return [ball, brick, broken]


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_a_batch_writes_every_good_part_and_reports_the_broken_one(parts, tmp_path, client):
    out = tmp_path / "out"
    records = run_batch(parts, SIZES, out, client=client)
    assert [(r["name"], r["voxel_size"]) for r in records] == [
        (n, s) for n in ("ball", "brick", "broken") for s in SIZES
    ]
    good = [r for r in records if r["name"] != "broken"]
    bad = [r for r in records if r["name"] == "broken"]
    assert all(r["ok"] and r["error"] is None for r in good)
    assert all(not r["ok"] and r["error_type"] == "MeshError" for r in bad)
    # The library's message, as the command line would give it.
    with pytest.raises(vps.MeshError) as e:
        vps.Mesh.load(parts[2])
    assert bad[0]["error"] == str(e.value)
    names = sorted(os.listdir(out))
    assert names == sorted(
        [SUMMARY] + [f"{n}@{s:g}.{ext}" for n in ("ball", "brick") for s in SIZES for ext in ("vxm", "vps")]
    ), "no temporary file is left and nothing is written for the broken part"
    for r in good:
        vm = vps.Voxmap.open(r["voxmap"])
        assert vm.voxel_size == r["voxel_size"] and vm.counts["surface_voxels"] == r["surface_voxels"]
        assert len(vps.Pointshell.open(r["pointshell"])) == r["points"]
        assert r["seconds"] > 0
    assert json.loads((out / SUMMARY).read_text()) == records
    # Both workers took part.
    assert len(client.scheduler_info()["workers"]) == 2


def test_the_command_line_runs_on_a_scheduler(parts, tmp_path, client, capsys):
    out = tmp_path / "cli"
    status = main([str(p) for p in parts[:2]] + ["--sizes", "0.5", "--out", str(out), "--no-pointshell",
                                                  "--scheduler", client.scheduler.address])
    assert status == 0
    assert sorted(os.listdir(out)) == sorted([SUMMARY, "ball@0.5.vxm", "brick@0.5.vxm"])
    assert "2 of 2 tasks succeeded" in capsys.readouterr().out
    assert main([str(parts[2]), "--sizes", "1", "--out", str(out), "--scheduler", client.scheduler.address]) == 1


def test_parts_of_the_same_name_get_files_of_their_own(tmp_path):
    a, b = tmp_path / "a" / "door.obj", tmp_path / "b" / "door.obj.zst"
    names = part_names([a, b, tmp_path / "hood.obj"])
    assert names[0] != names[1] and all(n.startswith("door-") for n in names[:2]) and names[2] == "hood"
    assert part_names([tmp_path / "roof.STL", tmp_path / "car.toml", tmp_path / "v1.2"]) == ["roof", "car", "v1.2"]
