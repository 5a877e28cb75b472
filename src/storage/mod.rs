//! The `.vxm` file: see `docs/FORMAT.md`.
