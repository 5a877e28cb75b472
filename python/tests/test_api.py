"""The Python package against the Rust command line on generated meshes."""

import json
import threading
import time

import numpy as np
import pytest

import vps
from conftest import box, sphere, write_obj

SIZE = 0.125


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """A sphere as arrays, as a vps.Mesh and as an OBJ file."""
    d = tmp_path_factory.mktemp("ball")
    v, t = sphere(radius=1.0)
    return v, t, vps.Mesh(v, t), write_obj(d / "ball.obj", v, t)


def test_mesh_from_arrays_and_from_file_agree(ball):
    v, t, mesh, obj = ball
    loaded = vps.Mesh.load(obj)
    assert mesh.triangle_count == loaded.triangle_count == len(t)
    np.testing.assert_array_equal(mesh.triangle_array(), loaded.triangle_array())
    np.testing.assert_array_equal(mesh.triangle_array()[:3], v[t[0]])
    lo, hi = mesh.bounds
    np.testing.assert_allclose(lo, v.min(axis=0))
    np.testing.assert_allclose(hi, v.max(axis=0))
    # Other dtypes and lists are converted.
    assert vps.Mesh(v.tolist(), t.astype(np.uint32)).triangle_count == len(t)


def test_a_scene_file_loads_as_its_placed_meshes(ball, tmp_path):
    _, t, mesh, obj = ball
    scene = tmp_path / "two.toml"
    scene.write_text(
        f'[[mesh]]\npath = "{obj.as_posix()}"\nname = "a"\n\n'
        f'[[mesh]]\npath = "{obj.as_posix()}"\nname = "b"\ntranslation = [10.0, 0.0, 0.0]\n'
    )
    two = vps.Mesh.load(scene)
    assert two.triangle_count == 2 * len(t)
    corners, one = two.triangle_array(), mesh.triangle_array()  # three rows per triangle
    np.testing.assert_array_equal(corners[: len(one)], one)
    np.testing.assert_allclose(corners[len(one) :], one + [10.0, 0.0, 0.0])
    scene.write_text("[[mesh]]\nname = 3\n")
    with pytest.raises(vps.MeshError, match="two.toml"):
        vps.Mesh.load(scene)


def test_voxelize_writes_the_same_file_as_the_command_line(ball, tmp_path, run_vps):
    _, _, mesh, obj = ball
    vm = vps.voxelize(mesh, SIZE, layers=5)
    py_file = tmp_path / "py.vxm"
    assert vm.write(py_file) == py_file.stat().st_size
    cli_file = tmp_path / "cli.vxm"
    run_vps("voxelize", obj, "--voxel-size", SIZE, "--layers", 5, "-o", cli_file)
    assert py_file.read_bytes() == cli_file.read_bytes()
    opened = vps.Voxmap.open(cli_file)
    assert opened.dims == vm.dims and opened.layers == vm.layers == 5
    assert opened.counts == vm.counts
    assert vm.report["triangles"] == mesh.triangle_count and not vm.report["leaks"]


def test_values_equal_probe(ball, tmp_path, run_vps):
    _, _, mesh, obj = ball
    cli_file = tmp_path / "cli.vxm"
    run_vps("voxelize", obj, "--voxel-size", SIZE, "-o", cli_file)
    rng = np.random.default_rng(7)
    points = rng.uniform(-1.6, 1.6, size=(2000, 3))
    points[:5] = [[0, 0, 0], [1, 0, 0], [0, 0, 1.0], [5, 5, 5], [-30, 0, 0]]
    pts_file = tmp_path / "points.txt"
    np.savetxt(pts_file, points, fmt="%.17g")
    probed = np.array(run_vps("probe", cli_file, "--points", pts_file).stdout.split(), dtype=np.int8)
    from_file = vps.Voxmap.open(cli_file).values(points)
    in_memory = vps.voxelize(mesh, SIZE).values(points)
    assert from_file.dtype == np.int8 and from_file.shape == (len(points),)
    np.testing.assert_array_equal(from_file, probed)
    np.testing.assert_array_equal(in_memory, probed)
    assert probed[0] > 0 and probed[3] < 0  # centre inside, far corner outside


def test_slice_holds_the_values_at_voxel_centres(ball):
    _, _, mesh, _ = ball
    vm = vps.voxelize(mesh, SIZE)
    nx, ny, nz = vm.dims
    ox, oy, oz = vm.origin
    s = vm.slice("z", at=0.01)
    assert s.dtype == np.int8 and s.shape == (ny, nx)
    k = int(np.floor((0.01 - oz) / SIZE))
    np.testing.assert_array_equal(vm.slice(2, index=k), s)
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    centres = np.stack([ox + (ix + 0.5) * SIZE, oy + (iy + 0.5) * SIZE, np.full(ix.shape, oz + (k + 0.5) * SIZE)], -1)
    expected = vm.values(centres.reshape(-1, 3)).reshape(ny, nx)[::-1]  # row 0 at the top
    np.testing.assert_array_equal(s, expected)
    with pytest.raises(vps.VpsError, match="outside the grid"):
        vm.slice("x", at=1e6)
    with pytest.raises(ValueError):
        vm.slice("w", index=0)


def test_pointshell_matches_the_command_line(ball, tmp_path, run_vps):
    _, _, mesh, obj = ball
    shell = vps.pointshell(mesh, voxel_size=SIZE)
    n = len(shell)
    assert n > 100
    assert shell.points.shape == (n, 3) and shell.normals.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(shell.normals, axis=1), 1.0, atol=1e-5)
    radii = np.linalg.norm(shell.points, axis=1)
    assert np.all(np.abs(radii - 1.0) < SIZE)  # on the sphere, within a voxel
    # Inward: the normal points against the radius.
    assert np.all(np.einsum("ij,ij->i", shell.points, shell.normals) < 0)
    py_file = tmp_path / "py.vps"
    shell.write(py_file)
    cli_file = tmp_path / "cli.vps"
    run_vps("pointshell", obj, "--voxel-size", SIZE, "-o", cli_file)
    assert py_file.read_bytes() == cli_file.read_bytes()
    opened = vps.Pointshell.open(cli_file)
    np.testing.assert_array_equal(opened.points, shell.points)
    np.testing.assert_array_equal(opened.normals, shell.normals)
    assert shell.weights.shape == (n,)
    assert np.all((shell.weights >= 1 / np.sqrt(3) - 1e-6) & (shell.weights <= 1))
    np.testing.assert_array_equal(opened.weights, shell.weights)


def test_contact_of_a_ball_pressed_into_a_box_pushes_it_out(tmp_path, run_vps):
    bv, bt = box((-2.0, -2.0, -2.0), (2.0, 2.0, 0.0))  # top face at z = 0
    wall = vps.voxelize(vps.Mesh(bv, bt), SIZE)
    ball_mesh = vps.Mesh(*sphere(radius=0.5))
    shell = vps.pointshell(ball_mesh, voxel_size=SIZE)
    pose = (0.1, -0.2, 0.2, 1.0, 0.0, 0.0, 0.0)  # centre 0.2 above the face: 0.3 pressed in
    c = vps.contact(wall, shell, pose)
    force, torque, touching = c
    assert touching == c.points_in_contact > 0
    assert force[2] > 0 and abs(force[0]) < 0.2 * force[2] and abs(force[1]) < 0.2 * force[2]
    assert c.complete and c.max_penetration > 0
    # The deepest point is on the ball's bottom, about as deep as the ball is pressed in.
    lowest = shell.points[c.deepest_point]
    assert lowest[2] < -0.45 and c.max_penetration == pytest.approx(0.3, abs=2 * SIZE)
    # The springs' energy, Σ ½·K·d² over the points pushing: positive, and linear in K.
    assert c.energy > 0
    assert vps.contact(wall, shell, pose, stiffness=2.0).energy == pytest.approx(2 * c.energy, rel=1e-12)
    assert vps.contact(wall, shell, (0.0, 0.0, 3.0)).points_in_contact == 0
    assert vps.contact(wall, shell, (0.0, 0.0, 3.0)).energy == 0
    # The same query from the command line, on the files.
    vxm, vps_file = tmp_path / "wall.vxm", tmp_path / "ball.vps"
    wall.write(vxm)
    shell.write(vps_file)
    out = run_vps("contact", vxm, vps_file, "--pose", " ".join(map(str, pose)), "--json").stdout
    cli = json.loads(out)
    np.testing.assert_array_equal(np.array(force), np.array(cli["force"]))
    assert cli["points_in_contact"] == c.points_in_contact
    file_contact = vps.contact(vps.Voxmap.open(vxm), vps.Pointshell.open(vps_file), pose)
    assert file_contact.force == c.force


def test_contact_interpolates_the_distances_of_a_voxmap_that_has_them(tmp_path):
    bv, bt = box((-2.0, -2.0, -2.0), (2.0, 2.0, 0.0))  # top face at z = 0
    wall = vps.voxelize(vps.Mesh(bv, bt), SIZE, distances=True)
    shell = vps.pointshell(vps.Mesh(*sphere(radius=0.5)), voxel_size=SIZE)
    pose = (0.1, -0.2, 0.2)
    smooth = vps.contact(wall, shell, pose)
    stepped = vps.contact(wall, shell, pose, penetration="layers")
    assert smooth.force[2] > 0 and stepped.force[2] > 0
    assert smooth.force != stepped.force
    # Written as a version 7 file, the same forces.
    wall.write(tmp_path / "wall.vxm")
    assert vps.contact(vps.Voxmap.open(tmp_path / "wall.vxm"), shell, pose).force == smooth.force
    with pytest.raises(ValueError, match="penetration"):
        vps.contact(wall, shell, pose, penetration="deep")


def test_the_sharp_penetration_keeps_a_box_edge(tmp_path):
    bv, bt = box((-2.0, -2.0, -2.0), (2.0, 2.0, 0.0))  # an edge along y at x = 2, z = 0
    wall = vps.voxelize(vps.Mesh(bv, bt), SIZE, distances=True)
    shell = vps.pointshell(vps.Mesh(*sphere(radius=0.5)), voxel_size=SIZE)
    on_face = (0.1, -0.2, 0.2)
    smooth = vps.contact(wall, shell, on_face)
    sharp = vps.contact(wall, shell, on_face, penetration="sharp")
    assert sharp.force[2] == pytest.approx(smooth.force[2], rel=0.01)
    # Pressed on the edge along the bisector of its faces: the trilinear blend cuts the ridge
    # of the distance there, the sharp one keeps it.
    c = (0.5 - 0.2) / np.sqrt(2.0)
    on_edge = (2.0 + c, 0.3, c)
    smooth = vps.contact(wall, shell, on_edge)
    sharp = vps.contact(wall, shell, on_edge, penetration="sharp")
    assert np.linalg.norm(sharp.force) > 1.05 * np.linalg.norm(smooth.force) > 0
    wall.write(tmp_path / "wall.vxm")
    from_file = vps.contact(vps.Voxmap.open(tmp_path / "wall.vxm"), shell, on_edge, penetration="sharp")
    assert from_file.force == sharp.force


def test_a_simulation_holds_a_ball_at_a_wall_it_is_pushed_through(tmp_path, run_vps):
    # A wall 2 voxels thick, the device pushed through it at 10 voxels per step and held
    # beyond: the object stays on the near side, the device is pulled back; the same from a
    # file (mapped) and from the command line, bit for bit.
    wv, wt = box((0.0, -2.0, -2.0), (2 * SIZE, 2.0, 2.0))
    wall = vps.voxelize(vps.Mesh(wv, wt), SIZE, distances=True)
    shell = vps.pointshell(vps.Mesh(*sphere(radius=0.5)), voxel_size=SIZE / 2)
    device = [(min(-1.0 + i * 10 * SIZE, 3.0), 0.0, 0.0, 1.0, 0.0, 0.0, 0.0) for i in range(80)]
    sim = vps.Simulation(wall, shell, device[0])
    steps = [sim.step(p) for p in device]
    for s in steps:
        deepest = s.pose[0] + 0.5  # the ball's radius
        assert deepest < SIZE, s
        assert s.max_penetration <= 0.25 * SIZE + 1e-12
    assert any(s.limited for s in steps)
    # Passive: no step ends with more energy than it began with plus the device's work.
    assert all(s.energy_gain <= 1e-9 * max(1.0, s.kinetic_energy + s.coupling_energy) for s in steps)
    assert all(s.energy_removed >= 0.0 for s in steps)
    assert steps[-1].device_force[0] < 0 and steps[-1].contact_force[0] < 0
    assert sim.pose == steps[-1].pose
    wall.write(tmp_path / "wall.vxm")
    shell.write(tmp_path / "ball.vps")
    mapped = vps.Simulation(vps.Voxmap.open(tmp_path / "wall.vxm"), vps.Pointshell.open(tmp_path / "ball.vps"), device[0])
    assert [mapped.step(p).device_force for p in device] == [s.device_force for s in steps]
    (tmp_path / "hand.txt").write_text("".join(" ".join(map(repr, p)) + "\n" for p in device))
    out = run_vps("simulate", tmp_path / "wall.vxm", tmp_path / "ball.vps", "--device", tmp_path / "hand.txt", "--json")
    assert json.loads(out.stdout)["final_pose"]["translation"] == list(steps[-1].pose[:3])
    # A step budget too short for any query: the object stays where a complete query put it.
    starved = vps.Simulation(wall, shell, device[0], budget_seconds=1e-9)
    assert all(starved.step(p).out_of_time for p in device[:5]) and starved.pose[:3] == list(device[0][:3])
    with pytest.raises(ValueError, match="budget_seconds"):
        vps.Simulation(wall, shell, device[0], budget_seconds=-1.0)
    with pytest.raises(ValueError, match="mass"):
        vps.Simulation(wall, shell, device[0], mass=0.0)
    # Given mass properties: accepted as 3, 6 or 9 numbers, checked.
    heavy = vps.Simulation(wall, shell, device[0], mass=2.0, inertia=[0.3, 0.3, 0.3], centre_of_mass=[0.0, 0.0, 0.0])
    full = vps.Simulation(wall, shell, device[0], mass=2.0, inertia=np.diag([0.3, 0.3, 0.3]).ravel(), centre_of_mass=(0, 0, 0))
    assert [heavy.step(p).device_force for p in device[:20]] == [full.step(p).device_force for p in device[:20]]
    with pytest.raises(ValueError, match="positive definite"):
        vps.Simulation(wall, shell, device[0], inertia=[1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match="3, 6 or 9"):
        vps.Simulation(wall, shell, device[0], inertia=[1.0, 1.0])
    with pytest.raises(ValueError, match="needs inertia"):
        vps.Simulation(wall, shell, device[0], centre_of_mass=[0.0, 0.0, 0.0])
    with pytest.raises(vps.HapticsError, match="deep"):
        vps.Simulation(wall, shell, (0.1, 0.0, 0.0))  # starts inside the wall


def test_errors_carry_the_library_messages(tmp_path, run_vps):
    missing = tmp_path / "missing.vxm"
    with pytest.raises(vps.StorageError) as e:
        vps.Voxmap.open(missing)
    assert isinstance(e.value, vps.VpsError)
    assert str(e.value) in run_vps("info", missing, check=False).stderr
    with pytest.raises(vps.MeshError, match="cannot read mesh"):
        vps.Mesh.load(tmp_path / "missing.obj")
    mesh = vps.Mesh(*box())
    with pytest.raises(vps.VpsError, match="^voxel size must be a positive finite number, got -1$"):
        vps.voxelize(mesh, -1.0)
    with pytest.raises(vps.GenerateError, match="layers must be at most 126, got 300"):
        vps.voxelize(mesh, 0.5, layers=300)
    with pytest.raises(vps.MeshError, match="non-finite"):
        vps.Mesh([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        vps.Mesh(np.zeros((4, 2)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="refers to vertex 7"):
        vps.Mesh(np.zeros((3, 3)), [[0, 1, 7]])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        vps.voxelize(mesh, 0.5).values(np.zeros(3))
    with pytest.raises(vps.HapticsError):
        vps.contact(vps.voxelize(mesh, 0.5), vps.pointshell(mesh, voxel_size=0.5), (0, 0, 0, 0, 0, 0, 0))


def test_voxelize_releases_the_gil():
    mesh = vps.Mesh(*sphere(radius=1.0, rings=48, segments=96))
    done = threading.Event()
    counter = [0]

    def spin():
        while not done.is_set():
            counter[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        # The thread's rate alone, while this one sleeps.
        c0 = counter[0]
        time.sleep(0.2)
        rate = (counter[0] - c0) / 0.2
        # Its count during voxelize calls only: holding the GIL, a call would let it run for
        # at most a switch interval (5 ms) around its start.
        during, elapsed = 0, 0.0
        while elapsed < 0.5:
            c0, start = counter[0], time.perf_counter()
            vps.voxelize(mesh, 0.01)
            elapsed += time.perf_counter() - start
            during += counter[0] - c0
    finally:
        done.set()
        t.join()
    assert during > 0.15 * rate * elapsed, f"counted {during} in {elapsed:.2f} s of voxelize, {rate:.0f}/s alone"
