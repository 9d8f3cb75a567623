//! Host-side wrappers: a dynamic plugin instance behind the core's plugin traits.
//!
//! They implement the typetag traits by hand: `typetag_name` returns the plugin's name (a
//! static of the never-unloaded library), so the resolved scene serialises as
//! `type = "name"` plus the parameters, exactly as it was written. (typetag's two hidden trait
//! methods are implemented here rather than through `#[typetag::serde]`, which would register a
//! fixed name; `resolved_scene_round_trips` in tests/dynplug.rs guards this.)
use std::ffi::c_void;
use std::mem::MaybeUninit;

use serde::{Serialize, Serializer};

use super::abi::{CFailureCheck, CFan, CLink, CPrincipal, ErrorOut, PluginEntry, RStr, STATUS_ERROR, STATUS_NONE, STATUS_OK, STATUS_PANIC};
use super::PluginInfo;
use crate::ids::EdgeId;
use crate::plugin::traits::{FailureCheck, FailureCriterion, FanView, ParamError, Principal, Proposal, SeparationRule};

/// One instance made by the plugin's `create`, or the parameter error it gave.
struct Instance {
    info: PluginInfo,
    entry: &'static PluginEntry,
    /// The scene's table without `type` (serialised back as written).
    params: toml::Table,
    ptr: *mut c_void,
    error: Option<ParamError>,
}

// SAFETY: the SDK requires plugin types to be Send + Sync; the pointer is only used through
// `&self` calls that the plugin trait allows from any thread.
unsafe impl Send for Instance {}
unsafe impl Sync for Instance {}

impl Instance {
    fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Instance {
        let mut params = match table {
            toml::Value::Table(t) => t,
            _ => toml::Table::new(),
        };
        params.remove("type");
        let mut inst = Instance { info, entry, params, ptr: std::ptr::null_mut(), error: None };
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
        let how = match st {
            STATUS_PANIC => "panicked",
            STATUS_ERROR => "failed",
            _ => "returned an unknown status",
        };
        let key = err.key();
        let key = if key.is_empty() { String::new() } else { format!(" ({key})") };
        format!("{} \"{}\" from {} {how} in {what}{key}: {}", self.info.kind, self.info.name, self.info.file.display(), err.msg())
    }

    fn live(&self) -> Result<*const c_void, String> {
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
const CHUNK: usize = 256;

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
        let cf = CFan { point: fan.point.0, cluster: fan.cluster.0, closed: fan.closed as u32, n_links: links.len(), links: links.as_ptr(), stress: fan.stress, principal: fan.principal.into() };
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
