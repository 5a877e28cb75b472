//! `vps._vps`: the native part of the `vps` Python package (docs/PYTHON.md).
//!
//! Thin bindings over the `vps` library: arrays in and out, each Rust error raised as a
//! subclass of `vps.VpsError` whose message is the error's `Display`, and the GIL released
//! while the library works. Nothing here decides what the library would.

mod arrays;
mod contact;
mod errors;
mod mesh;
mod pointshell;
mod simulation;
mod voxmap;

use pyo3::prelude::*;
use vps::voxmap::MAX_LAYERS;

/// The native module `vps._vps`; `import vps` re-exports it.
#[pymodule]
fn _vps(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("VpsError", py.get_type::<errors::VpsError>())?;
    m.add("MeshError", py.get_type::<errors::MeshError>())?;
    m.add("StorageError", py.get_type::<errors::StorageError>())?;
    m.add("GenerateError", py.get_type::<errors::GenerateError>())?;
    m.add("HapticsError", py.get_type::<errors::HapticsError>())?;
    m.add_class::<mesh::PyMesh>()?;
    m.add_class::<voxmap::PyVoxmap>()?;
    m.add_class::<pointshell::PyPointshell>()?;
    m.add_class::<contact::PyContact>()?;
    m.add_class::<simulation::PySimulation>()?;
    m.add_class::<simulation::PyStep>()?;
    m.add_function(wrap_pyfunction!(voxmap::voxelize, m)?)?;
    m.add_function(wrap_pyfunction!(pointshell::pointshell, m)?)?;
    m.add_function(wrap_pyfunction!(contact::contact, m)?)?;
    m.add("MAX_LAYERS", MAX_LAYERS)?;
    m.add("LEAF_SIZE", vps::LEAF_SIZE)?;
    Ok(())
}
