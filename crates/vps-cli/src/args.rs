//! Argument types and checks that several subcommands share: navigation, sizes in bytes, and
//! the voxelizing and haptic query parameters.

use std::time::Duration;

use anyhow::{bail, Result};
use clap::ValueEnum;

use vps::generate::Navigation;
use vps::{ContactParams, Penetration, VoxelizeParams};

/// `--navigation`: how candidate voxels are chosen in each triangle's bounding box.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum NavArg {
    Auto,
    Zrange,
    Narrowing,
    Bbox,
}

impl From<NavArg> for Navigation {
    fn from(n: NavArg) -> Navigation {
        match n {
            NavArg::Auto => Navigation::Auto,
            NavArg::Zrange => Navigation::ZRange,
            NavArg::Narrowing => Navigation::Narrowing,
            NavArg::Bbox => Navigation::BoundingBox,
        }
    }
}

/// Voxelizing parameters from `--voxel-size` and `--layers`, refused with the flag's name
/// when out of range.
pub fn voxelize_params(voxel_size: f64, layers: u32, navigation: Navigation) -> Result<VoxelizeParams> {
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        bail!("--voxel-size must be a positive number, got {voxel_size}");
    }
    if layers > vps::voxmap::MAX_LAYERS as u32 {
        bail!("--layers must be at most {}, got {layers}", vps::voxmap::MAX_LAYERS);
    }
    Ok(VoxelizeParams {
        voxel_size,
        layers: layers as u8,
        navigation,
        ..Default::default()
    })
}

/// `--penetration`: how deep a point in contact is (`docs/HAPTICS.md`).
#[derive(Clone, Copy, Debug, Default, ValueEnum)]
pub enum PenetrationArg {
    /// The interpolated sub-voxel signed distance (a voxmap without distances falls back to
    /// layers).
    #[default]
    Distance,
    /// The paper's layer depth plus the distance to the voxel centre's tangent plane.
    Layers,
    /// The signed distance blended so as to keep the ridges of convex edges and corners, which
    /// `distance` rounds off (eight times the look-ups; falls back to layers likewise).
    Sharp,
}

impl From<PenetrationArg> for Penetration {
    fn from(p: PenetrationArg) -> Penetration {
        match p {
            PenetrationArg::Distance => Penetration::Distance,
            PenetrationArg::Layers => Penetration::Layers,
            PenetrationArg::Sharp => Penetration::Sharp,
        }
    }
}

/// Haptic query parameters from `--stiffness`, `--budget-us` and `--penetration`.
pub fn contact_params(stiffness: f64, budget_us: Option<u64>, penetration: PenetrationArg) -> Result<ContactParams> {
    if !(stiffness.is_finite() && stiffness >= 0.0) {
        bail!("--stiffness must be a finite number >= 0, got {stiffness}");
    }
    Ok(ContactParams {
        stiffness,
        budget: budget_us.map(Duration::from_micros),
        penetration: penetration.into(),
    })
}

/// A byte count: a number with an optional unit, `k`/`M`/`G`/`T` (powers of 1000) or
/// `KiB`/`MiB`/`GiB`/`TiB` (powers of 1024); `B` alone or no unit means bytes.
pub fn parse_bytes(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    // The unit is the trailing run of letters: `2e9` has none, `4GiB` and `1.5e3 MB` do.
    let split = t.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len();
    let (num, unit) = (t[..split].trim(), t[split..].trim());
    let n: f64 = num
        .parse()
        .map_err(|_| format!("'{text}' is not a size: expected a number and a unit such as 4GiB"))?;
    let scale: f64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "m" | "mb" => 1e6,
        "g" | "gb" => 1e9,
        "t" | "tb" => 1e12,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => {
            return Err(format!(
                "'{text}': unknown unit '{unit}' (use B, MB, GB, MiB, GiB, ...)"
            ))
        }
    };
    let bytes = n * scale;
    if !(bytes.is_finite() && (1.0..1.8e19).contains(&bytes)) {
        return Err(format!("'{text}' is not a usable size"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_take_the_forms_the_help_shows() {
        assert_eq!(parse_bytes("2e9"), Ok(2_000_000_000));
        assert_eq!(parse_bytes("4GiB"), Ok(4 << 30));
        assert_eq!(parse_bytes("500MB"), Ok(500_000_000));
        assert_eq!(parse_bytes("1.5e3 MB"), Ok(1_500_000_000));
        assert_eq!(parse_bytes(" 512 MiB "), Ok(512 << 20));
        assert_eq!(parse_bytes("4096"), Ok(4096));
        for bad in ["", "GiB", "-1GiB", "4 parsecs", "1e400", "nan", "0"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }
}
