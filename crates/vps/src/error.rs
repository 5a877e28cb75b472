//! One error type over the library: each room keeps its own typed error, and every one of them
//! converts into [`Error`] with `?`, so a caller who voxelizes, writes and queries handles one.

use crate::generate::GenerateError;
use crate::geometry::PoseError;
use crate::grid::GridError;
use crate::haptics::trajectory::TrajectoryError;
use crate::haptics::HapticsError;
use crate::mesh::MeshError;
use crate::scene::SceneError;
use crate::storage::StorageError;
use crate::synth::SynthError;

/// Any error of the library; its message is the module error's. Boxed, so a `Result` stays
/// small on the success path.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or checking a mesh.
    #[error(transparent)]
    Mesh(Box<MeshError>),
    /// Reading or placing a scene file.
    #[error(transparent)]
    Scene(Box<SceneError>),
    /// A grid that cannot be made (voxel size, coordinates).
    #[error(transparent)]
    Grid(Box<GridError>),
    /// Voxelizing or sampling a pointshell.
    #[error(transparent)]
    Generate(Box<GenerateError>),
    /// Writing, opening or verifying a `.vxm` or `.vps` file.
    #[error(transparent)]
    Storage(Box<StorageError>),
    /// The contact query.
    #[error(transparent)]
    Haptics(Box<HapticsError>),
    /// A pose that is not a rigid motion.
    #[error(transparent)]
    Pose(Box<PoseError>),
    /// A trajectory file.
    #[error(transparent)]
    Trajectory(Box<TrajectoryError>),
    /// The synthetic car scene.
    #[error(transparent)]
    Synth(Box<SynthError>),
}

macro_rules! from_module_errors {
    ($($variant:ident($error:ty)),* $(,)?) => {
        $(impl From<$error> for Error {
            fn from(e: $error) -> Error {
                Error::$variant(Box::new(e))
            }
        })*
    };
}

from_module_errors!(
    Mesh(MeshError),
    Scene(SceneError),
    Grid(GridError),
    Generate(GenerateError),
    Storage(StorageError),
    Haptics(HapticsError),
    Pose(PoseError),
    Trajectory(TrajectoryError),
    Synth(SynthError),
);

/// A result with the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    /// A module's error goes through `?` into [`Error`] with its message unchanged.
    #[test]
    fn module_errors_convert_with_their_message() {
        let direct = crate::Mesh::from_triangles("empty", []).unwrap_err().to_string();
        let through = || -> Result<()> {
            crate::Mesh::from_triangles("empty", [])?;
            Ok(())
        };
        let e = through().unwrap_err();
        assert!(matches!(e, Error::Mesh(_)));
        assert_eq!(e.to_string(), direct);
        let missing = || -> Result<crate::VoxmapFile> { Ok(crate::VoxmapFile::open("no/such/file.vxm")?) };
        assert!(missing().unwrap_err().to_string().contains("no/such/file.vxm"));
    }
}
