//! `libvps`: the C ABI of `crates/vps-capi` under the library name C callers linked before the
//! workspace split (`-lvps`). It adds nothing: linking `vps_capi` exports its `#[no_mangle]`
//! functions from this cdylib too.

pub use vps_capi::*;
