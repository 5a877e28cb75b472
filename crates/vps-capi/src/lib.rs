//! The C ABI (header: `include/vps.h`, guide: `docs/C_ABI.md`).
//!
//! Two opaque handles — `vps_voxmap` over a [`CachedVoxmap`] and `vps_pointshell` over a
//! [`PointshellFile`] — and one query, `vps_contact` (or `vps_contact_with_params`, which also
//! picks the penetration formula). Both handles are read-only after they are
//! opened and are `Sync`, so any number of threads may query the same handles at once.
//!
//! Rules kept by every exported function:
//! - it never unwinds into C: its body runs under [`std::panic::catch_unwind`], and a panic
//!   becomes an error code (or a NULL handle) with its message in the caller's buffer;
//! - it checks every pointer for NULL before use, and touches a caller's pointer only in one
//!   small `unsafe` block whose `// SAFETY:` comment says which promise of the header it relies on;
//! - error messages are written NUL-terminated into `err` (at most `err_len` bytes, cut at a
//!   UTF-8 character boundary); `err` may be NULL or `err_len` 0 to ignore them.

use std::ffi::{c_char, c_double, c_int, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::time::Duration;

use vps::haptics::{HapticsError, Penetration};

mod simulation;
pub use simulation::*;
use vps::{contact, CachedVoxmap, ContactParams, PointshellFile, Pose};

/// Success.
pub const VPS_OK: c_int = 0;
/// A required pointer argument is NULL.
pub const VPS_ERR_NULL: c_int = 1;
/// The pose is not a rigid transform (a non-finite component or a zero quaternion).
pub const VPS_ERR_POSE: c_int = 2;
/// A parameter is out of range (stiffness negative or not finite, budget NaN).
pub const VPS_ERR_PARAM: c_int = 3;
/// A file could not be read (e.g. a corrupt brick, found when a query first reads it).
pub const VPS_ERR_STORAGE: c_int = 4;
/// An internal error (a panic, caught at the boundary). Please report it.
pub const VPS_ERR_INTERNAL: c_int = 5;

/// The penetration is the interpolated signed distance (the default; the layers when the
/// voxmap file has no distances).
pub const VPS_PENETRATION_DISTANCE: i32 = 0;
/// The penetration is the paper's layer formula, even when the file has distances.
pub const VPS_PENETRATION_LAYERS: i32 = 1;
/// The penetration is the signed distance blended so as to keep the ridges of convex edges and
/// corners (the layers when the voxmap file has no distances).
pub const VPS_PENETRATION_SHARP: i32 = 2;

/// `vps_contact_params` in C: what `vps_contact_with_params` asks for.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct VpsContactParams {
    /// Force per unit of penetration per point; finite and ≥ 0.
    pub stiffness: c_double,
    /// ≤ 0: the exact answer; > 0: the time-critical one, in microseconds.
    pub budget_us: c_double,
    /// [`VPS_PENETRATION_DISTANCE`], [`VPS_PENETRATION_LAYERS`] or [`VPS_PENETRATION_SHARP`].
    pub penetration: i32,
    /// Must be 0: room for a later field without a new function.
    pub reserved: i32,
}

/// `vps_voxmap` in C: an open `.vxm` file with its brick cache.
pub struct VpsVoxmap {
    inner: CachedVoxmap,
}

/// `vps_pointshell` in C: an open `.vps` file.
pub struct VpsPointshell {
    inner: PointshellFile,
}

// Handles are shared between C threads: both must be Send + Sync.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<VpsVoxmap>();
    assert_send_sync::<VpsPointshell>();
};

/// `vps_contact_result` in C: the result of a query (see [`vps::haptics::Contact`]).
///
/// Vectors are in the voxmap's world frame; torque is about the pose's translation.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VpsContactResult {
    /// Total force on the pointshell's object.
    pub force: [c_double; 3],
    /// Total torque about the posed pointshell origin.
    pub torque: [c_double; 3],
    /// Points tested that lie in a voxel with value ≥ 0.
    pub points_in_contact: u64,
    /// Points whose voxel was looked up.
    pub points_tested: u64,
    /// Sphere-tree nodes tested.
    pub nodes_tested: u64,
    /// Nodes skipped because the voxmap proves their sphere outside.
    pub nodes_culled: u64,
    /// Nodes whose points were not tested because the budget ran out.
    pub nodes_approximated: u64,
    /// Points below those nodes.
    pub points_approximated: u64,
    /// Largest penetration of a tested point, in world units.
    pub max_penetration: c_double,
    /// Wall time of the query, in microseconds.
    pub micros: c_double,
    /// Upper bound on `|force − exact force|` (0 when complete).
    pub force_error_bound: c_double,
    /// Upper bound on `|torque − exact torque|` (0 when complete).
    pub torque_error_bound: c_double,
    /// 1 when every point was tested (always, without a budget); 0 when the budget ran out.
    pub complete: i32,
    /// Always 0 (explicit padding, so the struct has no uninitialised bytes).
    pub reserved: i32,
    /// Energy in the contact's springs, `Σ ½·f·d` over the points pushing with `f` at depth `d`.
    pub energy: c_double,
    /// Index in the pointshell of a point `max_penetration` deep (see `Contact::deepest_point`);
    /// −1 when no tested point has a positive penetration.
    pub deepest_point: i64,
}

impl From<&vps::haptics::Contact> for VpsContactResult {
    fn from(c: &vps::haptics::Contact) -> VpsContactResult {
        VpsContactResult {
            force: c.force.to_array(),
            torque: c.torque.to_array(),
            points_in_contact: c.points_in_contact,
            points_tested: c.points_tested,
            nodes_tested: c.nodes_tested,
            nodes_culled: c.nodes_culled,
            nodes_approximated: c.nodes_approximated,
            points_approximated: c.points_approximated,
            max_penetration: c.max_penetration,
            micros: c.micros,
            force_error_bound: c.force_error_bound,
            torque_error_bound: c.torque_error_bound,
            complete: c.complete as i32,
            reserved: 0,
            energy: c.energy,
            deepest_point: c.deepest_point.map_or(-1, i64::from),
        }
    }
}

/// Where a function reports its message: the caller's `err` buffer of `err_len` bytes.
#[derive(Clone, Copy)]
struct ErrBuf {
    ptr: *mut c_char,
    len: usize,
}

impl ErrBuf {
    /// Write `msg`, cut to fit at a character boundary, and a NUL. No-op without a buffer.
    fn write(self, msg: &str) {
        if self.ptr.is_null() || self.len == 0 {
            return;
        }
        let mut n = msg.len().min(self.len - 1);
        while !msg.is_char_boundary(n) {
            n -= 1;
        }
        // SAFETY: the header requires `err` to be NULL or to point to `err_len` writable bytes;
        // it is not NULL here and we write `n + 1 <= err_len` bytes. `msg` is a Rust string, so
        // it cannot overlap the caller's buffer.
        unsafe {
            std::ptr::copy_nonoverlapping(msg.as_ptr(), self.ptr.cast::<u8>(), n);
            self.ptr.add(n).write(0);
        }
    }
}

/// The message of a caught panic.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    format!("internal error in vps (please report): {what}")
}

/// Run `body` so that no panic crosses the boundary: an error or a panic gives `on_error`, with
/// its message in `err`; success clears `err`.
fn guard<T>(err: ErrBuf, on_error: T, body: impl FnOnce() -> Result<T, String>) -> T {
    let (value, msg) = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(v)) => (v, String::new()),
        Ok(Err(msg)) => (on_error, msg),
        Err(payload) => (on_error, panic_message(payload.as_ref())),
    };
    err.write(&msg);
    value
}

/// A path from a C string: its bytes on Unix, UTF-8 elsewhere.
fn path_from_c(path: *const c_char) -> Result<PathBuf, String> {
    if path.is_null() {
        return Err("path is NULL".to_string());
    }
    // SAFETY: the header requires `path` to be a NUL-terminated string that stays valid for
    // the call; it is not NULL. The borrow ends before we return.
    let bytes = unsafe { CStr::from_ptr(path) }.to_bytes();
    if bytes.is_empty() {
        return Err("path is empty".to_string());
    }
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
    }
    #[cfg(not(unix))]
    {
        std::str::from_utf8(bytes)
            .map(PathBuf::from)
            .map_err(|e| format!("path is not UTF-8: {e}"))
    }
}

/// Move `value` to the heap and hand its pointer to C.
fn into_handle<T>(value: T) -> *mut T {
    Box::into_raw(Box::new(value))
}

/// Take back a handle from [`into_handle`] and drop it; NULL is a no-op. A panic while
/// dropping is caught: it has nowhere to be reported.
///
/// # Safety
/// `handle` must be NULL or from [`into_handle`], not yet freed, and no longer in use.
unsafe fn free_handle<T>(handle: *mut T) {
    if handle.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the caller's promise: made by `Box::into_raw`, freed once, unused, so we own
        // it again.
        drop(unsafe { Box::from_raw(handle) });
    }));
}

/// Open a `.vxm` voxmap and give a handle, or NULL with a message in `err`.
///
/// # Safety
/// `path` must be NULL or a NUL-terminated string; `err` must be NULL or point to `err_len`
/// writable bytes. Both need only live for the call.
#[no_mangle]
pub unsafe extern "C" fn vps_voxmap_open(path: *const c_char, err: *mut c_char, err_len: usize) -> *mut VpsVoxmap {
    let err = ErrBuf { ptr: err, len: err_len };
    guard(err, std::ptr::null_mut(), || {
        let path = path_from_c(path)?;
        let inner = CachedVoxmap::open(&path).map_err(|e| e.to_string())?;
        Ok(into_handle(VpsVoxmap { inner }))
    })
}

/// Open a `.vps` pointshell and give a handle, or NULL with a message in `err`.
///
/// # Safety
/// As [`vps_voxmap_open`].
#[no_mangle]
pub unsafe extern "C" fn vps_pointshell_open(
    path: *const c_char,
    err: *mut c_char,
    err_len: usize,
) -> *mut VpsPointshell {
    let err = ErrBuf { ptr: err, len: err_len };
    guard(err, std::ptr::null_mut(), || {
        let path = path_from_c(path)?;
        let inner = PointshellFile::open(&path).map_err(|e| e.to_string())?;
        Ok(into_handle(VpsPointshell { inner }))
    })
}

/// Close a voxmap handle and unmap its file. NULL is a no-op.
///
/// # Safety
/// `voxmap` must be NULL or a handle from [`vps_voxmap_open`] not yet closed, and no other
/// thread may be using it.
#[no_mangle]
pub unsafe extern "C" fn vps_voxmap_close(voxmap: *mut VpsVoxmap) {
    // SAFETY: the header requires NULL or a handle from `vps_voxmap_open`, closed once and no
    // longer in use.
    unsafe { free_handle(voxmap) }
}

/// Close a pointshell handle and unmap its file. NULL is a no-op.
///
/// # Safety
/// As [`vps_voxmap_close`], for a handle from [`vps_pointshell_open`].
#[no_mangle]
pub unsafe extern "C" fn vps_pointshell_close(pointshell: *mut VpsPointshell) {
    // SAFETY: as in `vps_voxmap_close`, for a handle from `vps_pointshell_open`.
    unsafe { free_handle(pointshell) }
}

/// The time budget of `budget_us` microseconds: `None` (exact) when ≤ 0 or too large to run out.
fn budget_of(budget_us: f64) -> Result<Option<Duration>, String> {
    if budget_us.is_nan() {
        return Err("budget_us is NaN (use 0 for an exact query)".to_string());
    }
    if budget_us <= 0.0 {
        return Ok(None);
    }
    Ok(Duration::try_from_secs_f64(budget_us * 1e-6).ok())
}

/// Force and torque of `voxmap` on `pointshell` at `pose`. Returns [`VPS_OK`] and fills `out`,
/// or an error code with a message in `err` (then `out` is left unchanged).
///
/// `pose` is 7 doubles `tx ty tz qw qx qy qz` (the quaternion is normalised); `stiffness` is
/// finite and ≥ 0; `budget_us` ≤ 0 asks for the exact answer, > 0 for the time-critical one.
/// The penetration is the default one: [`vps_contact_with_params`] chooses.
///
/// # Safety
/// `voxmap` and `pointshell` must be NULL or open handles; `pose` NULL or 7 readable doubles;
/// `out` NULL or a writable `vps_contact_result`; `err` NULL or `err_len` writable bytes.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn vps_contact(
    voxmap: *const VpsVoxmap,
    pointshell: *const VpsPointshell,
    pose: *const c_double,
    stiffness: c_double,
    budget_us: c_double,
    out: *mut VpsContactResult,
    err: *mut c_char,
    err_len: usize,
) -> c_int {
    let params = VpsContactParams {
        stiffness,
        budget_us,
        ..Default::default()
    };
    // SAFETY: the same promises as this function's, passed on; `params` is a live local.
    unsafe { vps_contact_with_params(voxmap, pointshell, pose, &params, out, err, err_len) }
}

/// [`vps_contact`] with its parameters in a struct, which also chooses the penetration
/// formula ([`VPS_PENETRATION_DISTANCE`], [`VPS_PENETRATION_LAYERS`] or
/// [`VPS_PENETRATION_SHARP`]).
///
/// # Safety
/// As [`vps_contact`], and `params` must be NULL or a readable `vps_contact_params`.
#[no_mangle]
pub unsafe extern "C" fn vps_contact_with_params(
    voxmap: *const VpsVoxmap,
    pointshell: *const VpsPointshell,
    pose: *const c_double,
    params: *const VpsContactParams,
    out: *mut VpsContactResult,
    err: *mut c_char,
    err_len: usize,
) -> c_int {
    let err = ErrBuf { ptr: err, len: err_len };
    guard_code(err, || {
        for (name, null) in [
            ("voxmap", voxmap.is_null()),
            ("pointshell", pointshell.is_null()),
            ("pose", pose.is_null()),
            ("params", params.is_null()),
            ("out", out.is_null()),
        ] {
            if null {
                return Err((VPS_ERR_NULL, format!("{name} is NULL")));
            }
        }
        // SAFETY: not NULL, and the header requires `params` to point to a readable
        // `vps_contact_params`; an unaligned read asks nothing more.
        let params = unsafe { params.read_unaligned() };
        // SAFETY: not NULL, and the header requires open handles, which stay valid (and are
        // only read, through `Sync` types) until the caller closes them after this call.
        let (voxmap, shell) = unsafe { (&(*voxmap).inner, &(*pointshell).inner) };
        // SAFETY: not NULL, and the header requires `pose` to point to 7 readable doubles.
        let pose = unsafe { read_pose(pose) }?;
        let params = contact_params(&params).map_err(|m| (VPS_ERR_PARAM, m))?;
        let c = contact(voxmap, shell, &pose, &params).map_err(|e| (code_of(&e), e.to_string()))?;
        // SAFETY: not NULL, and the header requires `out` to point to a writable `vps_contact_result`;
        // an unaligned write asks nothing more.
        unsafe { out.write_unaligned(VpsContactResult::from(&c)) };
        Ok(())
    })
}

/// Run `body` so that no panic crosses the boundary, for a function that returns a code: its
/// error's code and message, [`VPS_ERR_INTERNAL`] for a panic, or [`VPS_OK`] with `err`
/// cleared, so a caller never reads a stale message.
fn guard_code(err: ErrBuf, body: impl FnOnce() -> Result<(), (c_int, String)>) -> c_int {
    let (code, msg) = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => (VPS_OK, String::new()),
        Ok(Err(e)) => e,
        Err(payload) => (VPS_ERR_INTERNAL, panic_message(payload.as_ref())),
    };
    err.write(&msg);
    code
}

/// Read a pose of 7 doubles, `tx ty tz qw qx qy qz`.
///
/// # Safety
/// `pose` must point to 7 readable doubles.
unsafe fn read_pose(pose: *const c_double) -> Result<Pose, (c_int, String)> {
    // SAFETY: the caller's promise; an unaligned read asks nothing more.
    let p: [f64; 7] = unsafe { pose.cast::<[f64; 7]>().read_unaligned() };
    Pose::from_array(p).map_err(|e| (VPS_ERR_POSE, e.to_string()))
}

/// The return code of a query's error.
fn code_of(e: &HapticsError) -> c_int {
    match e {
        HapticsError::Storage(_) => VPS_ERR_STORAGE,
        HapticsError::Pose(_) => VPS_ERR_POSE,
        HapticsError::Params(_) => VPS_ERR_PARAM,
    }
}

/// The library's parameters for C's, or what is wrong with them (the stiffness is checked by
/// the query itself).
fn contact_params(p: &VpsContactParams) -> Result<ContactParams, String> {
    let penetration = match p.penetration {
        VPS_PENETRATION_DISTANCE => Penetration::Distance,
        VPS_PENETRATION_LAYERS => Penetration::Layers,
        VPS_PENETRATION_SHARP => Penetration::Sharp,
        other => {
            return Err(format!(
                "penetration {other} is none of VPS_PENETRATION_DISTANCE (0), VPS_PENETRATION_LAYERS (1) and VPS_PENETRATION_SHARP (2)"
            ))
        }
    };
    if p.reserved != 0 {
        return Err(format!("reserved is {}, must be 0", p.reserved));
    }
    Ok(ContactParams {
        stiffness: p.stiffness,
        budget: budget_of(p.budget_us)?,
        penetration,
    })
}

/// The library's version, e.g. `"0.3.0"`: a static NUL-terminated string, never freed.
#[no_mangle]
pub extern "C" fn vps_version() -> *const c_char {
    const VERSION: &CStr = match CStr::from_bytes_with_nul(concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes()) {
        Ok(v) => v,
        Err(_) => panic!("the version has an interior NUL"),
    };
    VERSION.as_ptr()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn contact_layout_is_the_headers() {
        // The offsets of `vps_contact_result` in include/vps.h, laid out by the C rules.
        assert_eq!(offset_of!(VpsContactResult, force), 0);
        assert_eq!(offset_of!(VpsContactResult, torque), 24);
        assert_eq!(offset_of!(VpsContactResult, points_in_contact), 48);
        assert_eq!(offset_of!(VpsContactResult, points_approximated), 88);
        assert_eq!(offset_of!(VpsContactResult, max_penetration), 96);
        assert_eq!(offset_of!(VpsContactResult, torque_error_bound), 120);
        assert_eq!(offset_of!(VpsContactResult, complete), 128);
        assert_eq!(offset_of!(VpsContactResult, reserved), 132);
        assert_eq!(offset_of!(VpsContactResult, energy), 136);
        assert_eq!(offset_of!(VpsContactResult, deepest_point), 144);
        assert_eq!(size_of::<VpsContactResult>(), 152);
        // And those of `vps_contact_params`.
        assert_eq!(offset_of!(VpsContactParams, budget_us), 8);
        assert_eq!(offset_of!(VpsContactParams, penetration), 16);
        assert_eq!(offset_of!(VpsContactParams, reserved), 20);
        assert_eq!(size_of::<VpsContactParams>(), 24);
    }

    #[test]
    fn params_choose_the_penetration_and_refuse_bad_values() {
        let p = |penetration, reserved| VpsContactParams {
            stiffness: 2.0,
            budget_us: 0.0,
            penetration,
            reserved,
        };
        let distance = contact_params(&p(VPS_PENETRATION_DISTANCE, 0)).unwrap();
        assert_eq!(distance.penetration, Penetration::Distance);
        assert_eq!(distance.stiffness, 2.0);
        assert_eq!(
            contact_params(&p(VPS_PENETRATION_LAYERS, 0)).unwrap().penetration,
            Penetration::Layers
        );
        assert_eq!(
            contact_params(&p(VPS_PENETRATION_SHARP, 0)).unwrap().penetration,
            Penetration::Sharp
        );
        assert!(contact_params(&p(3, 0)).unwrap_err().contains("penetration 3"));
        assert!(contact_params(&p(0, 7)).unwrap_err().contains("reserved"));
        // The zeroed struct is the default query.
        assert_eq!(
            contact_params(&VpsContactParams::default()).unwrap().penetration,
            Penetration::default()
        );
    }

    fn message(buf: &[c_char]) -> String {
        let bytes: Vec<u8> = buf.iter().take_while(|&&c| c != 0).map(|&c| c as u8).collect();
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn messages_are_cut_at_character_boundaries() {
        let mut buf = [1 as c_char; 6];
        let err = ErrBuf {
            ptr: buf.as_mut_ptr(),
            len: buf.len(),
        };
        err.write("abc€def"); // '€' is 3 bytes at 3..6: it does not fit in 5.
        assert_eq!(message(&buf), "abc");
        assert_eq!(buf[3], 0);
        err.write("ab");
        assert_eq!(message(&buf), "ab");
        // No buffer, or an empty one: nothing is written.
        ErrBuf {
            ptr: std::ptr::null_mut(),
            len: 10,
        }
        .write("x");
        let mut one = [1 as c_char; 1];
        ErrBuf {
            ptr: one.as_mut_ptr(),
            len: 0,
        }
        .write("x");
        assert_eq!(one[0], 1);
        ErrBuf {
            ptr: one.as_mut_ptr(),
            len: 1,
        }
        .write("x");
        assert_eq!(one[0], 0);
    }

    #[test]
    fn null_arguments_are_errors_not_crashes() {
        let mut buf = [0 as c_char; 64];
        // SAFETY: NULL handles and pointers are allowed by the header; `buf` is 64 writable bytes.
        unsafe {
            assert!(vps_voxmap_open(std::ptr::null(), buf.as_mut_ptr(), buf.len()).is_null());
            assert_eq!(message(&buf), "path is NULL");
            assert!(vps_pointshell_open(c"".as_ptr(), buf.as_mut_ptr(), buf.len()).is_null());
            assert_eq!(message(&buf), "path is empty");
            vps_voxmap_close(std::ptr::null_mut());
            vps_pointshell_close(std::ptr::null_mut());
            let mut out = VpsContactResult::default();
            let code = vps_contact(
                std::ptr::null(),
                std::ptr::null(),
                [0.0; 7].as_ptr(),
                1.0,
                0.0,
                &mut out,
                buf.as_mut_ptr(),
                buf.len(),
            );
            assert_eq!(code, VPS_ERR_NULL);
            assert_eq!(message(&buf), "voxmap is NULL");
        }
    }

    #[test]
    fn panics_become_errors() {
        let mut buf = [0 as c_char; 128];
        let err = ErrBuf {
            ptr: buf.as_mut_ptr(),
            len: buf.len(),
        };
        let r: i32 = guard(err, -1, || panic!("boom"));
        assert_eq!(r, -1);
        assert_eq!(message(&buf), "internal error in vps (please report): boom");
    }

    #[test]
    fn budgets() {
        assert_eq!(budget_of(0.0), Ok(None));
        assert_eq!(budget_of(-3.0), Ok(None));
        assert_eq!(budget_of(f64::INFINITY), Ok(None));
        assert_eq!(budget_of(250.0), Ok(Some(Duration::from_micros(250))));
        assert!(budget_of(f64::NAN).is_err());
    }

    #[test]
    fn version_is_the_crates() {
        // SAFETY: `vps_version` returns a static NUL-terminated string.
        let v = unsafe { CStr::from_ptr(vps_version()) };
        assert_eq!(v.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    }
}
