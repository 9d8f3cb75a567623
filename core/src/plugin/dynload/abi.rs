//! The C ABI between FLEM and a dynamic plugin library (plugin ABI version 3).
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
//!
//! # The kinds (ABI 2 and 3: criterion, separation, contact law, damping, material law)
//! Every kind has `create(params_json)`/`destroy` (the scene's table, parsed and validated by
//! the plugin) and its own functions in the [`PluginEntry`]; the others are null. State that a
//! plugin keeps between calls is never the plugin's: it is `n_state` f64 (declared in the
//! entry) per contact pair, per damping scheme or per integration point, in arrays the core
//! owns, passed by pointer to each call. So checkpoints, resume and bit-identical threads need
//! nothing from the plugin, and an instance is immutable after `create` (`*const`, callable
//! from any thread).
//! - **Contact law** ([`KIND_CONTACT`]): `contact_stiffness(inst)` (largest stiffness per unit
//!   area, the stable step) and `contact_evaluate(inst, n, kin, state, out, err)`: one call
//!   per step on the batch of pairs (chunks of at most 256), `kin[i]` the pair's kinematics
//!   in the master's frame ([`CPairKin`]), `state[3 i .. 3 i + n_state]` its history, updated
//!   in place (stride 3 whatever `n_state`: the pair's `PairState { en, es, max_open }`, where
//!   the core keeps it, so `n_state <= 3`, [`CONTACT_STATE_MAX`]), `out[i]` its force
//!   ([`CPairForce`]). Slots 0, 1
//!   are the normal and tangential spring forces, which the core scales by
//!   `sqrt(A_new / A_old)` when a split changes the pair's area (as for the built-ins).
//! - **Damping** ([`KIND_DAMPING`]): `damping_info(inst, out)` (whether it reads the Rayleigh
//!   sums, its stable-step factor), `damping_reset(inst, state, err)` at every stage start,
//!   `damping_coeffs(inst, stats, state, out, err)` once per step ([`CStepStats`] in,
//!   [`CDampingCoeffs`] out). The state is the checkpoint's damping section.
//! - **Material law** ([`KIND_MATERIAL`]): the scene's table makes a parameter instance
//!   (`create`); `law_bind(inst, material, out, err)` makes the law of one region from it and
//!   the region's elastic constants ([`CMaterial`]; errors name the law's key), freed by
//!   `law_destroy`. `law_elastic(law, out)` gives the elastic moduli `[d11, d12, d33]` (stable
//!   step, implicit check, initial tangent); `law_update(law, stress, deps, state, err)` is the
//!   stress update of one point (`stress` = `[sxx, syy, sxy, szz]` in/out, tension positive,
//!   `deps` = `[dexx, deyy, dgxy, dezz]`, `state` its `n_state` f64), called once per Gauss
//!   point per step from the core's stateful element block (one fn-pointer call per point; no
//!   other dispatch in the element loop); `law_output(law, state, gamma, flag)` what the output
//!   shows of a point's history (plastic shear strain, 0/1/2 plastic state).
//!
//! A status other than [`STATUS_OK`], or a non-finite number returned by a contact law, a
//! damping scheme or a material law, stops the run with an error naming the plugin and its
//! library (the wrapper records the fault; the solver's divergence guard reports it).
use std::ffi::c_void;

use crate::plugin::traits::{FailureCheck, FailureMode, Principal};

/// Version of this ABI (the layout of everything after the descriptor header). Bump it, and
/// the symbol name, whenever any type of this module changes.
pub const ABI_VERSION: u32 = 3;
/// The exported entry point: `extern "C" fn() -> *const Descriptor`. Its name stays the same
/// across ABI versions: the frozen header it returns says the version, so that a library of
/// another version is refused naming both versions (not only "no entry point").
pub const ENTRY_SYMBOL: &str = "flem_plugin_entry_v1";
/// The FLEM core version a library was built against (checked for equality).
pub const CORE_VERSION: &str = crate::VERSION;
/// The compiler that built this copy of flem-core (reported, not checked: no Rust type crosses).
pub const RUSTC_VERSION: &str = env!("FLEM_RUSTC_VERSION");

/// Plugin kinds.
pub const KIND_CRITERION: u32 = 1;
pub const KIND_SEPARATION: u32 = 2;
pub const KIND_CONTACT: u32 = 3;
pub const KIND_DAMPING: u32 = 4;
pub const KIND_MATERIAL: u32 = 5;

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

/// Contact law: the largest spring stiffness per unit area (stress / length).
pub type ContactStiffnessFn = unsafe extern "C" fn(instance: *const c_void) -> f64;
/// Contact law: `n` pairs; `state` holds `3 n` f64 (pair i's history in `3 i ..`, updated), `out` `n` forces (all
/// written on [`STATUS_OK`]).
pub type ContactEvaluateFn = unsafe extern "C" fn(instance: *const c_void, n: usize, kin: *const CPairKin, state: *mut f64, out: *mut CPairForce, err: *mut ErrorOut) -> i32;
/// Damping: what the scheme needs of the solver.
pub type DampingInfoFn = unsafe extern "C" fn(instance: *const c_void, out: *mut CDampingInfo);
/// Damping: start of a stage (`state`: `n_state` f64).
pub type DampingResetFn = unsafe extern "C" fn(instance: *const c_void, state: *mut f64, err: *mut ErrorOut) -> i32;
/// Damping: the coefficients of the next step.
pub type DampingCoeffsFn = unsafe extern "C" fn(instance: *const c_void, stats: *const CStepStats, state: *mut f64, out: *mut CDampingCoeffs, err: *mut ErrorOut) -> i32;
/// Material law: the law of one region (`out`, freed by [`LawDestroyFn`]) from the parameter
/// instance and the region's elastic constants.
pub type LawBindFn = unsafe extern "C" fn(instance: *const c_void, mat: *const CMaterial, out: *mut *mut c_void, err: *mut ErrorOut) -> i32;
/// Frees a law made by [`LawBindFn`].
pub type LawDestroyFn = unsafe extern "C" fn(law: *mut c_void);
/// Material law: elastic moduli `[d11, d12, d33]` (3 f64 written).
pub type LawElasticFn = unsafe extern "C" fn(law: *const c_void, out: *mut f64);
/// Material law: stress update of one point: `stress` 4 f64 in/out, `deps` 4 f64, `state`
/// `n_state` f64 in/out.
pub type LawUpdateFn = unsafe extern "C" fn(law: *const c_void, stress: *mut f64, deps: *const f64, state: *mut f64, err: *mut ErrorOut) -> i32;
/// Material law: `(plastic shear strain, plastic state 0/1/2)` of a point's history.
pub type LawOutputFn = unsafe extern "C" fn(law: *const c_void, state: *const f64, gamma: *mut f64, flag: *mut u8);

/// One plugin of a library.
#[repr(C)]
pub struct PluginEntry {
    /// [`KIND_CRITERION`], [`KIND_SEPARATION`], [`KIND_CONTACT`], [`KIND_DAMPING`] or
    /// [`KIND_MATERIAL`].
    pub kind: u32,
    pub name: RStr,
    pub create: CreateFn,
    pub destroy: DestroyFn,
    /// f64 of state per pair (contact, at most [`CONTACT_STATE_MAX`]), per scheme (damping)
    /// or per integration point (material); 0 for criteria and rules.
    pub n_state: usize,
    /// Set for a criterion.
    pub check_batch: Option<CheckBatchFn>,
    /// Set for a separation rule.
    pub propose: Option<ProposeFn>,
    /// Set for a contact law.
    pub contact_stiffness: Option<ContactStiffnessFn>,
    pub contact_evaluate: Option<ContactEvaluateFn>,
    /// Set for a damping scheme.
    pub damping_info: Option<DampingInfoFn>,
    pub damping_reset: Option<DampingResetFn>,
    pub damping_coeffs: Option<DampingCoeffsFn>,
    /// Set for a material law.
    pub law_bind: Option<LawBindFn>,
    pub law_destroy: Option<LawDestroyFn>,
    pub law_elastic: Option<LawElasticFn>,
    pub law_update: Option<LawUpdateFn>,
    pub law_output: Option<LawOutputFn>,
}

impl PluginEntry {
    /// An entry of `kind` with no kind functions (the SDK fills in those of its kind).
    pub const fn empty(kind: u32, name: &'static str, create: CreateFn, destroy: DestroyFn) -> PluginEntry {
        PluginEntry {
            kind,
            name: RStr::new(name),
            create,
            destroy,
            n_state: 0,
            check_batch: None,
            propose: None,
            contact_stiffness: None,
            contact_evaluate: None,
            damping_info: None,
            damping_reset: None,
            damping_coeffs: None,
            law_bind: None,
            law_destroy: None,
            law_elastic: None,
            law_update: None,
            law_output: None,
        }
    }

    /// The names of the functions its kind needs that it lacks (empty: complete).
    pub fn missing(&self) -> Vec<&'static str> {
        let need: &[(&'static str, bool)] = match self.kind {
            KIND_CRITERION => &[("check_batch", self.check_batch.is_some())],
            KIND_SEPARATION => &[("propose", self.propose.is_some())],
            KIND_CONTACT => &[("contact_stiffness", self.contact_stiffness.is_some()), ("contact_evaluate", self.contact_evaluate.is_some())],
            KIND_DAMPING => &[("damping_info", self.damping_info.is_some()), ("damping_reset", self.damping_reset.is_some()), ("damping_coeffs", self.damping_coeffs.is_some())],
            KIND_MATERIAL => &[
                ("law_bind", self.law_bind.is_some()),
                ("law_destroy", self.law_destroy.is_some()),
                ("law_elastic", self.law_elastic.is_some()),
                ("law_update", self.law_update.is_some()),
                ("law_output", self.law_output.is_some()),
            ],
            _ => &[],
        };
        need.iter().filter(|(_, ok)| !ok).map(|(n, _)| *n).collect()
    }
}

/// Most f64 of history a contact law may keep per pair: the core's `PairState` slots `en`,
/// `es`, `max_open`.
pub const CONTACT_STATE_MAX: usize = 3;

/// [`crate::contact::PairKinematics`] across the boundary (and whether the pair joins the two
/// faces of an edge split during the run: `fresh`, for cohesive laws).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CPairKin {
    pub gap: f64,
    pub dgap: f64,
    pub dslip: f64,
    pub vn: f64,
    pub vs: f64,
    pub area: f64,
    pub area_old: f64,
    pub dt: f64,
    /// 1 on the pair's first step.
    pub new: u32,
    /// 1 for a pair across a face split during the run.
    pub fresh: u32,
}

/// [`crate::contact::PairForce`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CPairForce {
    pub normal: f64,
    pub tangential: f64,
    pub stored: f64,
    pub dissipated: f64,
    /// 1: the pair stays in contact; 0: it opened (dropped).
    pub active: u32,
}

/// [`crate::plugin::damping::StepStats`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CStepStats {
    pub step: u64,
    pub dt: f64,
    pub omega_max: f64,
    pub kinetic: f64,
    pub u_f_int: f64,
    pub u_m_u: f64,
}

/// [`crate::plugin::damping::DampingCoeffs`] across the boundary.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CDampingCoeffs {
    pub viscous: f64,
    pub local: f64,
    pub eta: f64,
}

/// What a damping scheme needs of the solver.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CDampingInfo {
    /// 1: `coeffs` reads `u_f_int` and `u_m_u` (the solver sums them every step).
    pub uses_rayleigh_stats: u32,
    /// Factor (<= 1) on the critical time step.
    pub stability_factor: f64,
}

/// A region's elastic material ([`crate::element::Material`]); `plane` 0 stress, 1 strain.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct CMaterial {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
    pub thickness: f64,
    pub plane: u32,
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
    /// 1 when the point has never been split (`FanView::never_split`; ABI 3, issue 35: ABI 2
    /// had no field and the plugin saw `false`).
    pub never_split: u32,
    pub n_links: usize,
    pub links: *const CLink,
    pub stress: [f64; 3],
    pub principal: CPrincipal,
}

impl From<crate::element::Material> for CMaterial {
    fn from(m: crate::element::Material) -> Self {
        CMaterial { young: m.young, poisson: m.poisson, density: m.density, thickness: m.thickness, plane: (m.plane == crate::element::Plane::Strain) as u32 }
    }
}

impl From<CMaterial> for crate::element::Material {
    fn from(m: CMaterial) -> Self {
        let plane = if m.plane == 1 { crate::element::Plane::Strain } else { crate::element::Plane::Stress };
        crate::element::Material { young: m.young, poisson: m.poisson, density: m.density, thickness: m.thickness, plane }
    }
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

/// Writes `key` and `msg` into the `ErrorOut` at `p` through raw pointers (the host may pass a
/// slot whose bytes are not initialised: only its lengths are, see the contact and material
/// calls). Null: nothing.
///
/// # Safety
/// `p` is null or points to a writable `ErrorOut`.
pub unsafe fn write_err(p: *mut ErrorOut, key: &str, msg: &str) {
    if p.is_null() {
        return;
    }
    let cut = |s: &str, cap: usize| {
        let mut n = s.len().min(cap);
        while !s.is_char_boundary(n) {
            n -= 1;
        }
        n
    };
    let (kl, ml) = (cut(key, KEY_CAP), cut(msg, MSG_CAP));
    // SAFETY: in-bounds writes into the caller's ErrorOut.
    unsafe {
        std::ptr::copy_nonoverlapping(key.as_ptr(), std::ptr::addr_of_mut!((*p).key).cast::<u8>(), kl);
        std::ptr::copy_nonoverlapping(msg.as_ptr(), std::ptr::addr_of_mut!((*p).msg).cast::<u8>(), ml);
        std::ptr::addr_of_mut!((*p).key_len).write(kl);
        std::ptr::addr_of_mut!((*p).msg_len).write(ml);
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
