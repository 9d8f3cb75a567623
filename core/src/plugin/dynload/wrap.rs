//! Host-side wrappers: a dynamic plugin instance behind the core's plugin traits.
//!
//! They implement the typetag traits by hand: `typetag_name` returns the plugin's name (a
//! static of the never-unloaded library), so the resolved scene serialises as
//! `type = "name"` plus the parameters, exactly as it was written. (typetag's two hidden trait
//! methods are implemented here rather than through `#[typetag::serde]`, which would register a
//! fixed name; `resolved_scene_round_trips` in tests/dynplug.rs guards this.)
use std::ffi::c_void;
use std::mem::MaybeUninit;
use std::sync::{Arc, OnceLock};

use serde::{Serialize, Serializer};

use super::abi::{
    CDampingCoeffs, CDampingInfo, CFailureCheck, CFan, CLink, CMaterial, CPrincipal, CStepStats, ErrorOut, LawDestroyFn, LawOutputFn, LawUpdateFn, PluginEntry, RStr, KEY_CAP, MSG_CAP, STATUS_ERROR,
    STATUS_NONE, STATUS_OK, STATUS_PANIC,
};
use super::PluginInfo;
use crate::element::block::Block;
use crate::element::law::{LawCfg, MaterialLaw, RegionElems, StatefulOpts};
use crate::element::{Dmat, Material};
use crate::ids::EdgeId;
use crate::plugin::damping::{Damping, DampingCoeffs, StepStats};
use crate::plugin::traits::{FailureCheck, FailureCriterion, FanView, ParamError, Principal, Proposal, SeparationRule};

/// One instance made by the plugin's `create`, or the parameter error it gave.
pub(crate) struct Instance {
    pub(crate) info: PluginInfo,
    pub(crate) entry: &'static PluginEntry,
    /// The scene's table without `type` (serialised back as written).
    params: toml::Table,
    ptr: *mut c_void,
    pub(crate) error: Option<ParamError>,
    /// The first error of a call that cannot return one (contact, damping): reported by the
    /// solver (`fault()` of the traits) when the NaN it returned stops the run.
    pub(crate) fault: OnceLock<String>,
}

// SAFETY: the SDK requires plugin types to be Send + Sync; the pointer is only used through
// `&self` calls that the plugin trait allows from any thread.
unsafe impl Send for Instance {}
unsafe impl Sync for Instance {}

impl Instance {
    pub(crate) fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Instance {
        let mut params = match table {
            toml::Value::Table(t) => t,
            _ => toml::Table::new(),
        };
        params.remove("type");
        let mut inst = Instance { info, entry, params, ptr: std::ptr::null_mut(), error: None, fault: OnceLock::new() };
        let json = match serde_json::to_string(&inst.params) {
            Ok(j) => j,
            Err(e) => {
                inst.error = Some(ParamError::new("", format!("cannot be passed to the plugin: {e}")));
                return inst;
            }
        };
        let mut err = ErrorOut::default();
        let mut out: *mut c_void = std::ptr::null_mut();
        // SAFETY: ABI call; `json` and `err` outlive it.
        let st = unsafe { (entry.create)(RStr::new(&json), &mut out, &mut err) };
        match st {
            STATUS_OK if !out.is_null() => inst.ptr = out,
            STATUS_OK => inst.error = Some(ParamError::new("", format!("(plugin {} from {}) returned no instance", inst.info.name, inst.info.file.display()))),
            _ => {
                let what = if st == STATUS_PANIC { "the plugin panicked: " } else { "" };
                let key = err.key();
                let msg = err.msg();
                // The key names the parameter; the message gets the key's usual "key msg" form.
                inst.error = Some(ParamError::new(key, format!("{what}{msg} (plugin {} from {})", inst.info.name, inst.info.file.display())));
            }
        }
        inst
    }

    fn call_error(&self, what: &str, st: i32, err: &ErrorOut) -> String {
        call_fault(&self.who(), st, what, &err.key(), &err.msg())
    }

    /// Records the first fault (later ones are consequences).
    pub(crate) fn record(&self, msg: String) {
        let _ = self.fault.set(msg);
    }

    pub(crate) fn who(&self) -> String {
        format!("{} \"{}\" from {}", self.info.kind, self.info.name, self.info.file.display())
    }

    pub(crate) fn live(&self) -> Result<*const c_void, String> {
        match &self.error {
            Some(e) => Err(format!("{} \"{}\" from {} was not created: {e}", self.info.kind, self.info.name, self.info.file.display())),
            None => Ok(self.ptr),
        }
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if !self.ptr.is_null() {
            // SAFETY: made by this entry's `create`, freed once.
            unsafe { (self.entry.destroy)(self.ptr) };
        }
    }
}

impl std::fmt::Debug for Instance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} \"{}\" from {} {:?}", self.info.kind, self.info.name, self.info.file.display(), self.params)
    }
}

impl Serialize for Instance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.params.serialize(s)
    }
}

/// Points per call into the plugin: the batch lives on the stack (no allocation), and one
/// call costs ~10 ns, so per point the call is negligible.
pub(crate) const CHUNK: usize = 256;

/// A plugin instance behind one of the core's traits: the newtype, its constructor and its
/// library's info (the same for every plugin kind).
macro_rules! dyn_wrapper {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Debug, Serialize)]
        #[serde(transparent)]
        pub struct $name(Instance);

        impl $name {
            pub(super) fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Self {
                $name(Instance::new(info, entry, table))
            }
            pub fn info(&self) -> &PluginInfo {
                &self.0.info
            }
        }
    };
}

/// The trait methods every wrapper answers from its instance: the typetag name is the
/// plugin's, and `validate` returns the error the plugin gave when it was made.
macro_rules! instance_methods {
    () => {
        #[doc(hidden)]
        fn typetag_name(&self) -> &'static str {
            self.0.info.name
        }
        #[doc(hidden)]
        fn typetag_deserialize(&self) {}

        fn validate(&self) -> Result<(), ParamError> {
            self.0.error.clone().map_or(Ok(()), Err)
        }
    };
}
pub(crate) use instance_methods;

dyn_wrapper!(
    /// A failure criterion from a loaded library.
    DynCriterion
);

impl FailureCriterion for DynCriterion {
    instance_methods!();

    /// One point. The core always calls the batch form; an error here (only possible from a
    /// broken plugin) is reported as a panic of the host with the plugin's message.
    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let mut out = [FailureCheck::default()];
        self.try_check_batch(std::slice::from_ref(p), &[scale], &mut out).unwrap_or_else(|e| panic!("{e}"));
        out[0]
    }

    fn check_batch(&self, p: &[Principal], scale: &[f64], out: &mut [FailureCheck]) {
        self.try_check_batch(p, scale, out).unwrap_or_else(|e| panic!("{e}"))
    }

    fn try_check_batch(&self, p: &[Principal], scale: &[f64], out: &mut [FailureCheck]) -> Result<(), String> {
        let inst = self.0.live()?;
        let f = self.0.entry.check_batch.ok_or("no check_batch function")?;
        let n = p.len().min(scale.len()).min(out.len());
        // Not zeroed (a batch of one point would otherwise pay for 16 KB of memset): the host
        // writes every input before the call, and the ABI makes the plugin write every output
        // when it returns STATUS_OK.
        let mut cp = [const { MaybeUninit::<CPrincipal>::uninit() }; CHUNK];
        let mut co = [const { MaybeUninit::<CFailureCheck>::uninit() }; CHUNK];
        let mut err = ErrorOut::default(); // ~600 bytes
        let mut start = 0;
        while start < n {
            let m = CHUNK.min(n - start);
            for i in 0..m {
                cp[i].write(p[start + i].into());
            }
            // SAFETY: ABI call with m initialised inputs and m output slots.
            let st = unsafe { f(inst, m, cp.as_ptr().cast(), scale[start..].as_ptr(), co.as_mut_ptr().cast(), &mut err) };
            if st != STATUS_OK {
                return Err(self.0.call_error("check_batch", st, &err));
            }
            for i in 0..m {
                // SAFETY: written by the plugin (STATUS_OK).
                let c = unsafe { co[i].assume_init() };
                out[start + i] = c.to_check().map_err(|e| format!("criterion \"{}\" from {} {e}", self.0.info.name, self.0.info.file.display()))?;
            }
            start += m;
        }
        Ok(())
    }
}

dyn_wrapper!(
    /// A separation rule from a loaded library.
    DynSeparation
);

impl SeparationRule for DynSeparation {
    instance_methods!();

    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        self.try_propose(fan, failure).unwrap_or_else(|e| panic!("{e}"))
    }

    fn try_propose(&self, fan: &FanView, failure: &FailureCheck) -> Result<Option<Proposal>, String> {
        let inst = self.0.live()?;
        let f = self.0.entry.propose.ok_or("no propose function")?;
        let links: Vec<CLink> = fan.links.iter().map(|l| CLink { edge: l.edge.0, angle: l.angle, normal: l.normal }).collect();
        let cf = CFan {
            point: fan.point.0,
            cluster: fan.cluster.0,
            closed: fan.closed as u32,
            never_split: fan.never_split as u32,
            n_links: links.len(),
            links: links.as_ptr(),
            stress: fan.stress,
            principal: fan.principal.into(),
        };
        let chk = CFailureCheck::from(*failure);
        let mut edges = vec![0u32; links.len()];
        let mut len = 0usize;
        let mut err = ErrorOut::default();
        // SAFETY: ABI call; every buffer outlives it and `edges` has `links.len()` slots.
        let st = unsafe { f(inst, &cf, &chk, edges.as_mut_ptr(), edges.len(), &mut len, &mut err) };
        match st {
            STATUS_NONE => Ok(None),
            STATUS_OK => {
                if len > edges.len() {
                    return Err(format!("separation \"{}\" from {} proposed {len} edges for a fan of {} links", self.0.info.name, self.0.info.file.display(), links.len()));
                }
                Ok(Some(Proposal { edges: edges[..len].iter().map(|&e| EdgeId(e)).collect() }))
            }
            _ => Err(self.0.call_error("propose", st, &err)),
        }
    }
}

/// An [`ErrorOut`] for a hot call: only its two lengths are written (not its 600 bytes); the
/// plugin writes text and lengths when it fails, and [`read_err`] reads no further than them.
#[inline(always)]
pub(crate) fn err_slot() -> MaybeUninit<ErrorOut> {
    let mut e = MaybeUninit::<ErrorOut>::uninit();
    let p = e.as_mut_ptr();
    // SAFETY: writes to fields of a live allocation through raw pointers.
    unsafe {
        std::ptr::addr_of_mut!((*p).key_len).write(0);
        std::ptr::addr_of_mut!((*p).msg_len).write(0);
    }
    e
}

/// `(key, message)` of an [`err_slot`] after a call, without reading unwritten bytes.
#[cold]
pub(crate) fn read_err(e: &MaybeUninit<ErrorOut>) -> (String, String) {
    let p = e.as_ptr();
    // SAFETY: the lengths were written by `err_slot` or the plugin; the bytes below them by the
    // plugin (the ABI's contract for a failing call).
    unsafe {
        let kl = std::ptr::addr_of!((*p).key_len).read().min(KEY_CAP);
        let ml = std::ptr::addr_of!((*p).msg_len).read().min(MSG_CAP);
        let k = std::slice::from_raw_parts(std::ptr::addr_of!((*p).key).cast::<u8>(), kl);
        let m = std::slice::from_raw_parts(std::ptr::addr_of!((*p).msg).cast::<u8>(), ml);
        (String::from_utf8_lossy(k).into_owned(), String::from_utf8_lossy(m).into_owned())
    }
}

/// The one form of a failed plugin call (issue 35: it was formatted in four places, and the
/// damping's dropped the key): `{who} {how} in {function} ({key}): {msg}`, `how` from the
/// call's status ([`status_text`]), the key only when the plugin named one.
pub(crate) fn call_fault(who: &str, st: i32, function: &str, key: &str, msg: &str) -> String {
    let key = if key.is_empty() { String::new() } else { format!(" ({key})") };
    format!("{who} {} in {function}{key}: {msg}", status_text(st))
}

pub(crate) fn status_text(st: i32) -> &'static str {
    match st {
        STATUS_OK => "returned a non-finite number",
        STATUS_PANIC => "panicked",
        STATUS_ERROR => "failed",
        _ => "returned an unknown status",
    }
}

/// A damping scheme from a loaded library; its state (`n_state` f64) is kept here, in the
/// core, and goes to checkpoints through `state`/`set_state`.
#[derive(Debug, Serialize)]
#[serde(transparent)]
pub struct DynDamping {
    inst: Instance,
    #[serde(skip)]
    state: Vec<f64>,
    #[serde(skip)]
    info: CDampingInfo,
}

impl DynDamping {
    pub(super) fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Self {
        let inst = Instance::new(info, entry, table);
        let mut di = CDampingInfo { uses_rayleigh_stats: 1, stability_factor: 1.0 };
        if let (Ok(p), Some(f)) = (inst.live(), entry.damping_info) {
            // SAFETY: ABI call on a live instance.
            unsafe { f(p, &mut di) };
        }
        DynDamping { state: vec![0.0; entry.n_state], inst, info: di }
    }
    pub fn info(&self) -> &PluginInfo {
        &self.inst.info
    }
    fn fail(&self, msg: String) -> DampingCoeffs {
        self.inst.record(msg);
        DampingCoeffs { viscous: f64::NAN, local: f64::NAN, eta: f64::NAN }
    }
}

impl Damping for DynDamping {
    #[doc(hidden)]
    fn typetag_name(&self) -> &'static str {
        self.inst.info.name
    }
    #[doc(hidden)]
    fn typetag_deserialize(&self) {}

    fn validate(&self) -> Result<(), ParamError> {
        self.inst.error.clone().map_or(Ok(()), Err)
    }
    fn reset(&mut self) {
        let (Ok(p), Some(f)) = (self.inst.live(), self.inst.entry.damping_reset) else { return };
        let mut err = ErrorOut::default();
        // SAFETY: ABI call; the state has n_state slots.
        let st = unsafe { f(p, self.state.as_mut_ptr(), &mut err) };
        if st != STATUS_OK {
            let msg = call_fault(&self.inst.who(), st, "damping_reset", &err.key(), &err.msg());
            self.inst.record(msg);
            self.state.iter_mut().for_each(|x| *x = f64::NAN);
        }
    }
    fn coeffs(&mut self, stats: &StepStats) -> DampingCoeffs {
        let (p, f) = match (self.inst.live(), self.inst.entry.damping_coeffs) {
            (Ok(p), Some(f)) => (p, f),
            (Err(e), _) => return self.fail(e),
            (_, None) => return self.fail(format!("{} has no damping_coeffs", self.inst.who())),
        };
        let cs = CStepStats { step: stats.step, dt: stats.dt, omega_max: stats.omega_max, kinetic: stats.kinetic, u_f_int: stats.u_f_int, u_m_u: stats.u_m_u };
        let mut out = CDampingCoeffs::default();
        let mut err = ErrorOut::default();
        // SAFETY: ABI call; the state has n_state slots.
        let st = unsafe { f(p, &cs, self.state.as_mut_ptr(), &mut out, &mut err) };
        if st != STATUS_OK {
            return self.fail(call_fault(&self.inst.who(), st, "damping_coeffs", &err.key(), &err.msg()));
        }
        if !(out.viscous + out.local + out.eta + self.state.iter().sum::<f64>()).is_finite() {
            return self.fail(format!(
                "{} returned non-finite damping coefficients (viscous {}, local {}, eta {}) or state {:?} at step {}",
                self.inst.who(),
                out.viscous,
                out.local,
                out.eta,
                self.state,
                stats.step
            ));
        }
        DampingCoeffs { viscous: out.viscous, local: out.local, eta: out.eta }
    }
    fn uses_rayleigh_stats(&self) -> bool {
        self.info.uses_rayleigh_stats != 0
    }
    fn stability_factor(&self) -> f64 {
        self.info.stability_factor
    }
    fn state(&self) -> Vec<f64> {
        self.state.clone()
    }
    fn set_state(&mut self, s: &[f64]) {
        if s.len() == self.state.len() {
            self.state.copy_from_slice(s);
        }
    }
    fn fault(&self) -> Option<String> {
        self.inst.fault.get().cloned()
    }
}

/// `[[material]] law = { type = "<a loaded material law>", ... }`: the parameter instance;
/// each region's law is bound from it and the region's elastic constants ([`DynLaw`]).
#[derive(Debug, Clone)]
pub struct DynLawCfg(Arc<Instance>);

impl Serialize for DynLawCfg {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl DynLawCfg {
    pub(super) fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Self {
        DynLawCfg(Arc::new(Instance::new(info, entry, table)))
    }
    pub fn info(&self) -> &PluginInfo {
        &self.0.info
    }

    /// The law of a region with material `mat`, or `(key, message)`.
    pub fn bind(&self, mat: &Material) -> Result<DynLaw, (String, String)> {
        let inst = &self.0;
        if let Some(e) = &inst.error {
            return Err((e.key.clone(), e.msg.clone()));
        }
        let e = inst.entry;
        let (Some(bind), Some(destroy), Some(elastic), Some(update), Some(output)) = (e.law_bind, e.law_destroy, e.law_elastic, e.law_update, e.law_output) else {
            return Err((String::new(), format!("{} lacks a material-law function", inst.who())));
        };
        let cm = CMaterial::from(*mat);
        let mut out: *mut c_void = std::ptr::null_mut();
        let mut err = ErrorOut::default();
        // SAFETY: ABI call; every pointer outlives it.
        let st = unsafe { bind(inst.ptr, &cm, &mut out, &mut err) };
        if st != STATUS_OK || out.is_null() {
            let what = if st == STATUS_PANIC { "the plugin panicked: " } else { "" };
            let msg = if st == STATUS_OK { "returned no law".to_string() } else { err.msg() };
            return Err((err.key(), format!("{what}{msg} (plugin {} from {})", inst.info.name, inst.info.file.display())));
        }
        let mut d = [0.0; 3];
        // SAFETY: ABI call on the bound law; 3 slots.
        unsafe { elastic(out, d.as_mut_ptr()) };
        let bound = Bound { who: inst.who(), ptr: out, update, output, destroy, d: Dmat { d11: d[0], d12: d[1], d33: d[2] }, ns: e.n_state, fault: OnceLock::new() };
        if !(d[0] + d[1] + d[2]).is_finite() {
            return Err((String::new(), format!("{} returned non-finite elastic moduli {d:?}", inst.who())));
        }
        Ok(DynLaw(Arc::new(bound)))
    }
}

impl LawCfg for DynLawCfg {
    #[doc(hidden)]
    fn typetag_name(&self) -> &'static str {
        self.0.info.name
    }
    #[doc(hidden)]
    fn typetag_deserialize(&self) {}

    fn validate(&self, mat: &Material) -> Result<(), (String, String)> {
        self.bind(mat).map(|_| ())
    }
    fn build(&self, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>> {
        // `validate` ran on this material when the scene was read: binding again cannot fail
        // but for a plugin that is not deterministic, which is a defect of the plugin.
        let law = self.bind(&mat).unwrap_or_else(|(k, m)| panic!("region \"{region}\": the material law's {k} {m} (it validated before)"));
        let mut builders = inventory::iter::<DynLawBlocks>.into_iter();
        let first = builders.next();
        debug_assert!(builders.next().is_none(), "more than one DynLawBlocks submitted: the choice between them would be arbitrary");
        match first {
            Some(b) => (b.0)(law, region, mat, opts, elems),
            // No element kinds linked (a core-only binary): `Model::new` then refuses the
            // region naming its element key, as for any law without blocks.
            None => Vec::new(),
        }
    }
    fn clone_box(&self) -> Box<dyn LawCfg> {
        Box::new(self.clone())
    }
}

/// The stateful blocks of a dynamic law for a region: the element kinds live in the plugins
/// crate, which submits this constructor (`flem_plugins::elements`: one `StatefulBlock<S,
/// DynLaw, N>` per kind, monomorphised there, like a built-in law's).
pub struct DynLawBlocks(pub fn(DynLaw, &str, Material, StatefulOpts, &RegionElems) -> Vec<Box<dyn Block>>);
inventory::collect!(DynLawBlocks);

/// A region's material law from a loaded library: one call through a function pointer per
/// integration point per step, inside the core's stateful block (monomorphised for this type,
/// so no other dispatch); its history lives in the block's arrays.
#[derive(Clone, Debug)]
pub struct DynLaw(Arc<Bound>);

#[derive(Debug)]
struct Bound {
    who: String,
    ptr: *mut c_void,
    update: LawUpdateFn,
    output: LawOutputFn,
    destroy: LawDestroyFn,
    d: Dmat,
    ns: usize,
    fault: OnceLock<String>,
}

// SAFETY: the SDK requires laws to be Send + Sync; the pointer is only used through `*const`
// calls.
unsafe impl Send for Bound {}
unsafe impl Sync for Bound {}

impl Drop for Bound {
    fn drop(&mut self) {
        // SAFETY: made by law_bind, freed once.
        unsafe { (self.destroy)(self.ptr) };
    }
}

impl DynLaw {
    #[cold]
    #[inline(never)]
    fn fail(&self, st: i32, err: &MaybeUninit<ErrorOut>, old: [f64; 4], de: [f64; 4], s: &mut [f64; 4], state: &[f64]) {
        let b = &*self.0;
        let msg = if st == STATUS_OK {
            format!("{} returned a non-finite stress {s:?} or history {state:?} (stress before {old:?}, strain increment {de:?})", b.who)
        } else {
            let (key, msg) = read_err(err);
            format!("{} (stress before {old:?}, strain increment {de:?})", call_fault(&b.who, st, "law_update", &key, &msg))
        };
        let _ = b.fault.set(msg);
        *s = [f64::NAN; 4];
    }
}

impl MaterialLaw for DynLaw {
    /// Unused: the block reads [`MaterialLaw::n_state`], the library's declared length.
    const STATE: usize = 0;
    #[inline(always)]
    fn n_state(&self) -> usize {
        self.0.ns
    }
    fn elastic(&self) -> Dmat {
        self.0.d
    }
    #[inline(always)]
    fn update(&self, s: &mut [f64; 4], de: [f64; 4], state: &mut [f64]) {
        let b = &*self.0;
        let old = *s;
        let mut err = err_slot();
        // SAFETY: ABI call: 4 stress slots, 4 increments, n_state history slots (the block's
        // slice for this point).
        let st = unsafe { (b.update)(b.ptr, s.as_mut_ptr(), de.as_ptr(), state.as_mut_ptr(), err.as_mut_ptr()) };
        let mut sum = s[0] + s[1] + s[2] + s[3];
        for &x in state.iter() {
            sum += x;
        }
        if st != STATUS_OK || !sum.is_finite() {
            self.fail(st, &err, old, de, s, state);
        }
    }
    fn output(&self, state: &[f64]) -> (f64, u8) {
        let (mut g, mut f) = (0.0, 0u8);
        // SAFETY: ABI call; n_state slots in.
        unsafe { (self.0.output)(self.0.ptr, state.as_ptr(), &mut g, &mut f) };
        (g, f)
    }
    fn fault(&self) -> Option<String> {
        self.0.fault.get().cloned()
    }
}
