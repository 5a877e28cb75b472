//! The exception classes, `vps.VpsError` and one subclass per kind of Rust error, and the
//! conversion of each Rust error into its class. The Rust error types are named by their
//! paths here, as the classes take their names.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;
use pyo3::PyResult;
use vps::storage::slice::SliceError;

create_exception!(
    vps,
    VpsError,
    PyException,
    "Base class of the errors of the vps library."
);
create_exception!(vps, MeshError, VpsError, "A mesh could not be read or is unusable.");
create_exception!(
    vps,
    StorageError,
    VpsError,
    "A .vxm or .vps file could not be read or written."
);
create_exception!(
    vps,
    GenerateError,
    VpsError,
    "Voxelization or pointshell generation failed."
);
create_exception!(vps, HapticsError, VpsError, "A contact query failed.");

/// A Rust error as the Python exception of its kind, with the error's message.
pub(crate) trait ToPy {
    /// The exception, with the error's message.
    fn to_py(self) -> PyErr;
}

impl ToPy for vps::mesh::MeshError {
    fn to_py(self) -> PyErr {
        MeshError::new_err(self.to_string())
    }
}

impl ToPy for vps::storage::StorageError {
    fn to_py(self) -> PyErr {
        StorageError::new_err(self.to_string())
    }
}

impl ToPy for vps::generate::GenerateError {
    fn to_py(self) -> PyErr {
        match self {
            vps::generate::GenerateError::Storage(e) => e.to_py(),
            e => GenerateError::new_err(e.to_string()),
        }
    }
}

impl ToPy for vps::haptics::HapticsError {
    fn to_py(self) -> PyErr {
        match self {
            vps::haptics::HapticsError::Storage(e) => e.to_py(),
            e => HapticsError::new_err(e.to_string()),
        }
    }
}

impl ToPy for vps::Error {
    fn to_py(self) -> PyErr {
        match self {
            vps::Error::Mesh(e) => (*e).to_py(),
            vps::Error::Storage(e) => (*e).to_py(),
            vps::Error::Generate(e) => (*e).to_py(),
            vps::Error::Haptics(e) => (*e).to_py(),
            // A scene file is read where a mesh is.
            vps::Error::Scene(e) => MeshError::new_err(e.to_string()),
            e => VpsError::new_err(e.to_string()),
        }
    }
}

impl ToPy for SliceError {
    fn to_py(self) -> PyErr {
        match self {
            SliceError::Storage(e) => e.to_py(),
            e => VpsError::new_err(e.to_string()),
        }
    }
}

/// `Result<T, E>` → `PyResult<T>` through [`ToPy`].
pub(crate) trait OrRaise<T> {
    /// The value, or the error raised as its exception.
    fn or_raise(self) -> PyResult<T>;
}

impl<T, E: ToPy> OrRaise<T> for Result<T, E> {
    fn or_raise(self) -> PyResult<T> {
        self.map_err(ToPy::to_py)
    }
}
