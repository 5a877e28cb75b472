//! Memory budgets: how much a run will hold at its peak, estimated from the mesh and the grid
//! before anything large is allocated, and how much memory the machine has.
//!
//! The estimate counts surface voxels from the triangles' areas and perimeters (a triangle
//! of area `A` and perimeter `P` touches at most about `√3·A/s² + 2·P/s + 8` voxels of size
//! `s`), then charges each surface voxel the bytes the in-memory path was measured to use
//! per surface voxel (`docs/PERFORMANCE.md`: about 30 bytes with 5 layers on the synthetic
//! car, 28–30 over a 20× range of voxel counts), with a margin. It does not scale with the
//! grid's volume, only with its surface.

use crate::mesh::Mesh;

use crate::generate::VoxelizeParams;

/// Fraction of the machine's memory a run may use when the user sets no limit.
pub const DEFAULT_BUDGET_FRACTION: f64 = 0.5;

/// Bytes of a pointshell point in memory while it is made: position, normal, tree order.
const POINT_BYTES: f64 = 48.0;

/// Safety margin on the per-voxel figures measured.
const MARGIN: f64 = 1.5;

/// A run's expected peak, before it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryEstimate {
    /// The mesh as loaded.
    pub mesh_bytes: u64,
    /// Surface voxels expected (an upper estimate).
    pub surface_voxels: f64,
    /// The whole run's peak, mesh included.
    pub peak_bytes: u64,
}

/// Bytes the in-memory voxelizer holds per surface voxel with `layers` layers.
fn bytes_per_surface_voxel(layers: u8) -> f64 {
    (10.0 + 4.0 * layers as f64) * MARGIN
}

/// Upper estimate of the surface voxels of `mesh` at voxel size `s`.
pub fn surface_voxels(mesh: &Mesh, s: f64) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (t[1] - t[0], t[2] - t[1], t[0] - t[2]);
            let area = 0.5 * a.cross(c).length();
            let perimeter = a.length() + b.length() + c.length();
            3f64.sqrt() * area / (s * s) + 2.0 * perimeter / s + 8.0
        })
        .sum()
}

/// Bytes the signed distances add per surface voxel with `layers` layers, at their peak (each
/// stored brick's distances, 1 KiB, the triangle lists that find them, and the nearest
/// triangles of the bricks being worked on). Measured on Nefertiti at voxel 0.5225 with 5
/// layers: 148 MB more for 1.89 million surface voxels (65,106 stored bricks), 78 bytes each.
fn distance_bytes_per_surface_voxel(layers: u8) -> f64 {
    (40.0 + 8.0 * layers as f64) * MARGIN
}

/// The in-memory voxelizer's expected peak for `mesh` with `params`.
pub fn voxelize_in_memory(mesh: &Mesh, params: &VoxelizeParams) -> MemoryEstimate {
    let mesh_bytes = mesh.approx_bytes();
    let surface = surface_voxels(mesh, params.voxel_size);
    let per_voxel = bytes_per_surface_voxel(params.layers)
        + if params.distances {
            distance_bytes_per_surface_voxel(params.layers)
        } else {
            0.0
        };
    let peak = mesh_bytes as f64 + surface * per_voxel;
    MemoryEstimate {
        mesh_bytes,
        surface_voxels: surface,
        peak_bytes: saturating_bytes(peak),
    }
}

/// The pointshell command's expected peak: a voxmap of `params` in memory and one point per
/// surface voxel.
pub fn pointshell(mesh: &Mesh, params: &VoxelizeParams) -> MemoryEstimate {
    let v = voxelize_in_memory(mesh, params);
    let peak = v.peak_bytes as f64 + v.surface_voxels * POINT_BYTES * MARGIN;
    MemoryEstimate {
        peak_bytes: saturating_bytes(peak),
        ..v
    }
}

/// `b` bytes as a whole number, `u64::MAX` when beyond it (or not a number).
fn saturating_bytes(b: f64) -> u64 {
    b.min(u64::MAX as f64) as u64
}

/// The memory of this machine, or of the control group the process runs in when that is
/// smaller: `/proc/meminfo` and cgroup v2 `memory.max` (v1 `memory.limit_in_bytes`). `None`
/// where neither can be read.
pub fn physical_memory() -> Option<u64> {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        kib.checked_mul(1024)
    });
    let cgroup = [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ]
    .iter()
    .filter_map(|p| std::fs::read_to_string(p).ok())
    .filter_map(|t| t.trim().parse::<u64>().ok())
    .min();
    match (total, cgroup) {
        (Some(t), Some(c)) => Some(t.min(c)),
        (t, c) => t.or(c),
    }
}

/// The budget of a run with no limit given: [`DEFAULT_BUDGET_FRACTION`] of
/// [`physical_memory`], or `None` when that is unknown.
pub fn default_budget() -> Option<u64> {
    physical_memory().map(|m| (m as f64 * DEFAULT_BUDGET_FRACTION) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimates_follow_the_surface_not_the_volume() {
        // Triangles larger than the voxels, as in the runs the budget matters for (fine
        // tessellations at coarse voxels are overestimated by the perimeter terms).
        let sphere = crate::shapes::sphere(glam::DVec3::ZERO, 10.0, 8, 16);
        let mesh = Mesh::from_triangles("s", sphere).unwrap();
        let params = |s| VoxelizeParams {
            voxel_size: s,
            layers: 5,
            ..Default::default()
        };
        let (coarse, fine) = (
            voxelize_in_memory(&mesh, &params(0.5)),
            voxelize_in_memory(&mesh, &params(0.25)),
        );
        // Half the voxel size: four times the area term, twice the perimeter term, eight
        // times the volume.
        let ratio = fine.surface_voxels / coarse.surface_voxels;
        assert!((2.0..4.5).contains(&ratio), "{ratio}");
        // The estimate bounds the surface the voxelizer finds.
        let (vm, _) = crate::generate::voxelize(&mesh, &params(0.25)).unwrap();
        let found = vm.counts().surface_voxels as f64;
        assert!(
            fine.surface_voxels >= found && fine.surface_voxels < 4.0 * found,
            "{} vs {found}",
            fine.surface_voxels
        );
        assert!(pointshell(&mesh, &params(0.25)).peak_bytes > fine.peak_bytes);
    }

    #[test]
    fn huge_estimates_saturate() {
        let mesh = Mesh::from_triangles(
            "t",
            [[
                glam::DVec3::ZERO,
                glam::DVec3::new(130.0, 0.0, 0.0),
                glam::DVec3::new(0.0, 130.0, 0.0),
            ]],
        )
        .unwrap();
        let e = voxelize_in_memory(
            &mesh,
            &VoxelizeParams {
                voxel_size: 1e-3,
                layers: 5,
                ..Default::default()
            },
        );
        assert!(e.peak_bytes > 100 << 30, "{e:?}");
        assert!(physical_memory().is_none_or(|m| m > 0));
    }
}
