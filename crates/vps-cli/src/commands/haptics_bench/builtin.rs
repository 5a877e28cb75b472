//! `vps haptics-bench --builtin`: a big sphere's voxmap and a small sphere's pointshell, built
//! on the spot at the sizes asked for, so the bench needs no input file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::DVec3;
use serde_json::{json, Value};

use vps::generate::{voxelize_with, Navigation};
use vps::{write_pointshell, write_voxmap, Grid, Mesh, VoxelizeParams};

/// What `--builtin` made.
pub struct Built {
    /// The static object's voxmap.
    pub voxmap: PathBuf,
    /// The moving object's pointshell.
    pub pointshell: PathBuf,
    /// Seconds to build both.
    pub seconds: f64,
    /// Sizes, counts and times, for the report.
    pub info: Value,
}

/// Largest distance, in voxels, between the built spheres' facets and the true sphere.
const SPHERE_SAG_VOXELS: f64 = 0.02;

/// Pointshell points (one per surface voxel) of a voxelized sphere per `area / voxel_size²`:
/// the SAT surface is thicker than one voxel where it runs diagonally. Measured with this
/// builder: 1.501 at 20,000 points (radius 32 voxels) and 1.500 at 10⁶ (radius 227 voxels).
const SPHERE_SURFACE_DENSITY: f64 = 1.50;

/// Layers of the built-in voxmaps.
const BUILTIN_LAYERS: u8 = 5;

/// A UV sphere at the origin, tessellated finely enough for voxels of `voxel_size`.
fn sphere_mesh(name: &str, radius: f64, voxel_size: f64) -> Result<Mesh> {
    let rings = vps::shapes::sphere_rings(radius / voxel_size, SPHERE_SAG_VOXELS);
    Ok(Mesh::from_triangles(
        name,
        vps::shapes::sphere(DVec3::ZERO, radius, rings, 2 * rings),
    )?)
}

/// Voxelizing parameters of the built-in objects.
fn builtin_params(voxel_size: f64) -> VoxelizeParams {
    VoxelizeParams {
        voxel_size,
        layers: BUILTIN_LAYERS,
        navigation: Navigation::Auto,
        ..Default::default()
    }
}

/// Build the `--builtin` files in `dir`: a big sphere of radius 1000 voxelized so that its
/// grid has at least `grid_voxels` voxels, and the pointshell of a sphere a quarter its radius,
/// sampled at the voxel size that gives about `points` points.
pub fn build_builtin(dir: &Path, points: f64, grid_voxels: f64) -> Result<Built> {
    if !(points.is_finite() && (100.0..=1e8).contains(&points)) {
        bail!("--points must be between 100 and 1e8, got {points}");
    }
    if !(grid_voxels.is_finite() && (1e4..=1e12).contains(&grid_voxels)) {
        bail!("--grid-voxels must be between 1e4 and 1e12, got {grid_voxels}");
    }
    let start = Instant::now();
    let big_r = 1000.0;
    let pad = BUILTIN_LAYERS as u32 + 2;
    let (lo, hi) = (DVec3::splat(-big_r), DVec3::splat(big_r));
    // The grid is the sphere's box plus padding, rounded up to bricks. Start from a voxel too
    // big for the target and shrink it by 0.5% steps until the grid has enough voxels, so the
    // grid ends just over the target.
    let mut s = 1.5 * 2.0 * big_r / grid_voxels.cbrt();
    let mut grid = Grid::around(lo, hi, s, pad)?;
    for _ in 0..1000 {
        if grid.voxel_count() as f64 >= grid_voxels {
            break;
        }
        s *= 0.995;
        grid = Grid::around(lo, hi, s, pad)?;
    }
    let big = sphere_mesh("static sphere", big_r, s)?;
    errln!(
        "builtin: voxelizing a sphere of radius {big_r} ({} triangles) at voxel size {s:.4}: grid {} × {} × {} = {} voxels",
        big.triangles.len(),
        grid.dims[0],
        grid.dims[1],
        grid.dims[2],
        grid.voxel_count()
    );
    let t = Instant::now();
    // With distances, so the bench measures the default penetration; `--penetration layers`
    // measures the paper's on the same file.
    let params = VoxelizeParams {
        distances: true,
        ..builtin_params(s)
    };
    let (vm, _) = voxelize_with(&big, &params, &|_| {})?;
    let vxm = dir.join("builtin_static.vxm");
    crate::interrupt::clean_beside(&vxm)?;
    let w = write_voxmap(&vxm, &vm).with_context(|| format!("writing {}", vxm.display()))?;
    let voxmap_seconds = t.elapsed().as_secs_f64();
    let counts = vm.counts();
    drop(vm);
    drop(big);

    let small_r = big_r / 4.0;
    let v = small_r * (4.0 * std::f64::consts::PI * SPHERE_SURFACE_DENSITY / points).sqrt();
    let small = sphere_mesh("moving sphere", small_r, v)?;
    errln!(
        "builtin: pointshell of a sphere of radius {small_r} ({} triangles) at voxel size {v:.4}",
        small.triangles.len()
    );
    let t = Instant::now();
    let (svm, _) = voxelize_with(&small, &builtin_params(v), &|_| {})?;
    let (shell, _) = vps::pointshell(&small, &svm, vps::LEAF_SIZE)?;
    drop(svm);
    let vps_path = dir.join("builtin_moving.vps");
    let ps_bytes = write_pointshell(&vps_path, &shell).with_context(|| format!("writing {}", vps_path.display()))?;
    let pointshell_seconds = t.elapsed().as_secs_f64();
    let info = json!({
        "static_sphere_radius": big_r,
        "voxel_size": s,
        "grid_dims": grid.dims,
        "grid_voxels": grid.voxel_count(),
        "surface_voxels": counts.surface_voxels,
        "bricks_stored": counts.bricks_stored,
        "voxmap_file_bytes": w.file_bytes,
        "voxmap_seconds": voxmap_seconds,
        "moving_sphere_radius": small_r,
        "pointshell_voxel_size": v,
        "points": shell.len(),
        "pointshell_file_bytes": ps_bytes,
        "pointshell_seconds": pointshell_seconds,
    });
    Ok(Built {
        voxmap: vxm,
        pointshell: vps_path,
        seconds: start.elapsed().as_secs_f64(),
        info,
    })
}
