//! The subcommands, one file each: its arguments and a `run` that checks them, calls the
//! library and prints.

pub mod bench;
pub mod contact;
pub mod demo;
pub mod export;
pub mod haptics_bench;
pub mod info;
pub mod pointshell;
pub mod probe;
pub mod scene;
pub mod simulate;
pub mod slice;
pub mod verify;
pub mod voxelize;
