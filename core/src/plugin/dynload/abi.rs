//! The C ABI between FLEM and a dynamic plugin library (plugin ABI version 1).
//!
//! Only `#[repr(C)]` types of this module cross the boundary (no Rust `Vec`, `String`, trait
//! object or allocation): the host and the plugin may be built by different compilers, and
//! each frees only what it allocated. Strings are `(pointer, length)` pairs of UTF-8 that stay
//! valid as long as their owner does (the library's statics: forever, since a library is never
//! unloaded; a call argument: during the call).
//!
//! The library exports one function, [`ENTRY_SYMBOL`] (`flem_plugin_entry_v1`), returning a
//! pointer to a static [`Descriptor`]. Its first three fields (the header: ABI version, FLEM
//! core version, compiler version) are frozen for every ABI version: the host reads them, and
//! nothing else, before it accepts the library. Every plugin function returns a status
//! ([`STATUS_OK`] ...) and writes an error into a host-owned [`ErrorOut`]; a panic is caught by
//! the plugin side (the SDK's shims) and returned as [`STATUS_PANIC`], never unwound across
//! `extern "C"` (that would abort the process).
use std::ffi::c_void;

use crate::plugin::traits::{FailureCheck, FailureMode, Principal};

/// Version of this ABI (the layout of everything after the descriptor header). Bump it, and
/// the symbol name, whenever any type of this module changes.
pub const ABI_VERSION: u32 = 1;
/// The exported entry point: `extern "C" fn() -> *const Descriptor`.
pub const ENTRY_SYMBOL: &str = "flem_plugin_entry_v1";
/// The FLEM core version a library was built against (checked for equality).
pub const CORE_VERSION: &str = crate::VERSION;
/// The compiler that built this copy of flem-core (reported, not checked: no Rust type crosses).
pub const RUSTC_VERSION: &str = env!("FLEM_RUSTC_VERSION");

/// Plugin kinds.
pub const KIND_CRITERION: u32 = 1;
pub const KIND_SEPARATION: u32 = 2;

/// Statuses returned by plugin functions.
pub const STATUS_OK: i32 = 0;
/// `propose`: no proposal (the rule declines to cut).
pub const STATUS_NONE: i32 = 1;
/// Bad parameters or a failed call; `ErrorOut` says why (and which key).
pub const STATUS_ERROR: i32 = 2;
/// The plugin panicked; `ErrorOut.msg` has the panic message.
pub const STATUS_PANIC: i32 = 3;

/// A borrowed UTF-8 string.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct RStr {
    pub ptr: *const u8,
    pub len: usize,
}

// SAFETY: an `RStr` is a shared view of immutable bytes (statics or call arguments).
unsafe impl Send for RStr {}
unsafe impl Sync for RStr {}

impl RStr {
    pub const fn new(s: &str) -> RStr {
        RStr { ptr: s.as_ptr(), len: s.len() }
    }

    /// The text.
    ///
    /// # Safety
    /// `ptr` must point to `len` readable bytes that outlive `'a` (or be null with `len` 0).
    pub unsafe fn as_str<'a>(&self) -> Result<&'a str, std::str::Utf8Error> {
        if self.ptr.is_null() || self.len == 0 {
            return Ok("");
        }
        // SAFETY: the caller guarantees the range is readable for 'a.
        std::str::from_utf8(unsafe { std::slice::from_raw_parts(self.ptr, self.len) })
    }
}

/// What a library provides. The first three fields are the header (frozen across ABI versions).
#[repr(C)]
pub struct Descriptor {
    pub abi_version: u32,
    pub core_version: RStr,
    pub rustc_version: RStr,
    // --- ABI 1 body: read only after the header matched.
    pub n_plugins: usize,
    pub plugins: *const PluginEntry,
}

// SAFETY: descriptors are immutable statics of the library.
unsafe impl Sync for Descriptor {}
unsafe impl Send for Descriptor {}

/// `create(params_json, &mut instance, &mut err) -> status`: builds an instance from the
/// scene's parameter table (JSON text, without `type`) and validates it.
pub type CreateFn = unsafe extern "C" fn(params_json: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32;
/// Frees an instance made by `create`.
pub type DestroyFn = unsafe extern "C" fn(instance: *mut c_void);
/// Criterion batch: `n` points in, `n` checks out (on [`STATUS_OK`] every output is written;
/// the host does not initialise them).
pub type CheckBatchFn = unsafe extern "C" fn(instance: *const c_void, n: usize, p: *const CPrincipal, scale: *const f64, out: *mut CFailureCheck, err: *mut ErrorOut) -> i32;
/// Separation rule: writes up to `cap` edge ids and their count, or returns [`STATUS_NONE`].
pub type ProposeFn = unsafe extern "C" fn(instance: *const c_void, fan: *const CFan, failure: *const CFailureCheck, out_edges: *mut u32, cap: usize, out_len: *mut usize, err: *mut ErrorOut) -> i32;

/// One plugin of a library.
#[repr(C)]
pub struct PluginEntry {
    /// [`KIND_CRITERION`] or [`KIND_SEPARATION`].
    pub kind: u32,
    pub name: RStr,
    pub create: CreateFn,
    pub destroy: DestroyFn,
    /// Set for a criterion.
    pub check_batch: Option<CheckBatchFn>,
    /// Set for a separation rule.
    pub propose: Option<ProposeFn>,
}

// SAFETY: immutable statics of the library.
unsafe impl Sync for PluginEntry {}
unsafe impl Send for PluginEntry {}

/// [`Principal`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CPrincipal {
    pub s1: f64,
    pub s3: f64,
    pub s2: f64,
    pub theta1: f64,
}

impl From<Principal> for CPrincipal {
    fn from(p: Principal) -> Self {
        CPrincipal { s1: p.s1, s3: p.s3, s2: p.s2, theta1: p.theta1 }
    }
}

impl From<CPrincipal> for Principal {
    fn from(p: CPrincipal) -> Self {
        Principal { s1: p.s1, s3: p.s3, s2: p.s2, theta1: p.theta1 }
    }
}

/// [`FailureCheck`] across the boundary: `mode` 0 holds, 1 tension, 2 shear.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CFailureCheck {
    pub index: f64,
    pub planes: [f64; 2],
    pub mode: u32,
    pub n_planes: u32,
}

impl From<FailureCheck> for CFailureCheck {
    fn from(c: FailureCheck) -> Self {
        let mode = match c.mode {
            None => 0,
            Some(FailureMode::Tension) => 1,
            Some(FailureMode::Shear) => 2,
        };
        CFailureCheck { index: c.index, planes: c.planes, mode, n_planes: c.n_planes as u32 }
    }
}

impl CFailureCheck {
    /// Back to the core type; an out-of-range mode or plane count is an error.
    pub fn to_check(self) -> Result<FailureCheck, String> {
        let mode = match self.mode {
            0 => None,
            1 => Some(FailureMode::Tension),
            2 => Some(FailureMode::Shear),
            m => return Err(format!("returned failure mode {m} (0 holds, 1 tension, 2 shear)")),
        };
        if self.n_planes > 2 {
            return Err(format!("returned {} failure planes (at most 2)", self.n_planes));
        }
        Ok(FailureCheck { index: self.index, mode, planes: self.planes, n_planes: self.n_planes as u8 })
    }
}

/// [`crate::plugin::traits::LinkGeom`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CLink {
    pub edge: u32,
    pub angle: f64,
    pub normal: [f64; 2],
}

/// [`crate::plugin::traits::FanView`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct CFan {
    pub point: u32,
    pub cluster: u32,
    /// 1 for a closed fan (a cycle of links), 0 for a path.
    pub closed: u32,
    pub n_links: usize,
    pub links: *const CLink,
    pub stress: [f64; 3],
    pub principal: CPrincipal,
}

/// Capacity of [`ErrorOut::key`] and [`ErrorOut::msg`] (longer text is cut at a char boundary).
pub const KEY_CAP: usize = 64;
pub const MSG_CAP: usize = 512;

/// An error written by the plugin into host memory: the parameter key (may be empty) and the
/// message.
#[repr(C)]
pub struct ErrorOut {
    pub key: [u8; KEY_CAP],
    pub key_len: usize,
    pub msg: [u8; MSG_CAP],
    pub msg_len: usize,
}

impl Default for ErrorOut {
    fn default() -> Self {
        ErrorOut { key: [0; KEY_CAP], key_len: 0, msg: [0; MSG_CAP], msg_len: 0 }
    }
}

impl ErrorOut {
    /// Copies `key` and `msg`, cut to the capacity at a char boundary.
    pub fn set(&mut self, key: &str, msg: &str) {
        self.key_len = copy_cut(&mut self.key, key);
        self.msg_len = copy_cut(&mut self.msg, msg);
    }
    pub fn key(&self) -> String {
        String::from_utf8_lossy(&self.key[..self.key_len.min(KEY_CAP)]).into_owned()
    }
    pub fn msg(&self) -> String {
        String::from_utf8_lossy(&self.msg[..self.msg_len.min(MSG_CAP)]).into_owned()
    }
}

fn copy_cut(dst: &mut [u8], s: &str) -> usize {
    let mut n = s.len().min(dst.len());
    while !s.is_char_boundary(n) {
        n -= 1;
    }
    dst[..n].copy_from_slice(&s.as_bytes()[..n]);
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Conversions round-trip; a bad mode is refused; long messages are cut at a char boundary.
    #[test]
    fn conversions_and_error_text() {
        let c = FailureCheck { index: 1.5, mode: Some(FailureMode::Shear), planes: [0.1, 0.2], n_planes: 2 };
        assert_eq!(CFailureCheck::from(c).to_check().unwrap(), c);
        let bad = CFailureCheck { mode: 7, ..Default::default() };
        assert!(bad.to_check().unwrap_err().contains("mode 7"));
        let mut e = ErrorOut::default();
        let long = "é".repeat(MSG_CAP);
        e.set("k", &long);
        assert_eq!(e.key(), "k");
        assert!(e.msg().chars().all(|c| c == 'é') && e.msg_len <= MSG_CAP && e.msg_len % 2 == 0);
    }
}
