//! `flem-plugin-sdk`: write a FLEM failure criterion or separation rule in your own crate, build
//! it as a shared library (`crate-type = ["cdylib"]`) and load it from a scene with
//! `[plugins] load = ["path/to/libyours.so"]`, without rebuilding FLEM.
//!
//! A plugin author writes one trait impl ([`Criterion`] or [`Separation`]) on a
//! `serde::Deserialize` parameter struct, and one registration line:
//!
//! ```ignore
//! flem_plugin_sdk::export_plugins!(criterion "my_rankine" => MyRankine);
//! ```
//!
//! The macro exports the C entry point `flem_plugin_entry_v1` (see
//! [`flem_core::plugin::dynload::abi`]) with the FLEM core version and compiler this SDK was built with;
//! the host refuses a library built for another core or ABI version. The shims here:
//! - parse the scene's parameter table (JSON text) into your struct; an unknown, missing or
//!   ill-typed key is reported with the key's name ([`serde_path_to_error`]);
//! - call your `validate()` (errors name the key: [`ParamError::range`]);
//! - call your `check` for every point of a batch (one C call per batch of points, your code
//!   monomorphised inside the loop);
//! - catch every panic (a panic crossing `extern "C"` would abort the host) and return it as an
//!   error that the host reports with the plugin's name and file.
//!
//! See docs/plugins.md and the tested example crate `plugins/example`.
use std::any::Any;
use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use flem_core::ids::{ClusterId, EdgeId, PointId};
pub use flem_core::plugin::dynload::abi;
pub use flem_core::plugin::traits::{line_angle, principal, ray_angle, FailureCheck, FailureMode, FanView, LinkGeom, ParamError, Principal, Proposal};
pub use serde;

use abi::{
    CFailureCheck, CFan, CPrincipal, Descriptor, ErrorOut, PluginEntry, RStr, ABI_VERSION, CORE_VERSION, KIND_CRITERION, KIND_SEPARATION, RUSTC_VERSION, STATUS_ERROR, STATUS_NONE, STATUS_OK,
    STATUS_PANIC,
};
use serde::de::DeserializeOwned;

/// A failure criterion (the dynamic twin of [`flem_core::plugin::traits::FailureCriterion`]).
/// Inputs are compression positive; `scale` multiplies the strengths at this point.
pub trait Criterion: DeserializeOwned + Send + Sync + 'static {
    /// Checks the parameters; the error names the key and the allowed range.
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    fn check(&self, p: &Principal, scale: f64) -> FailureCheck;
}

/// A separation rule (the dynamic twin of [`flem_core::plugin::traits::SeparationRule`]).
pub trait Separation: DeserializeOwned + Send + Sync + 'static {
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    /// The edges to cut at a failed point (at most the fan's number of links), or `None`.
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal>;
}

/// Exports the plugins of this library: `kind "name" => Type`, with kind `criterion` or
/// `separation`. Use it once per library.
#[macro_export]
macro_rules! export_plugins {
    ($($kind:ident $name:literal => $ty:ty),+ $(,)?) => {
        /// The FLEM plugin entry point (plugin ABI 1).
        #[unsafe(no_mangle)]
        pub extern "C" fn flem_plugin_entry_v1() -> *const $crate::abi::Descriptor {
            static PLUGINS: &[$crate::abi::PluginEntry] = &[$($crate::__entry!($kind $name $ty)),+];
            static DESCRIPTOR: $crate::abi::Descriptor = $crate::descriptor(PLUGINS);
            &DESCRIPTOR
        }
    };
}

#[doc(hidden)]
#[macro_export]
macro_rules! __entry {
    (criterion $name:literal $ty:ty) => {
        $crate::criterion_entry::<$ty>($name)
    };
    (separation $name:literal $ty:ty) => {
        $crate::separation_entry::<$ty>($name)
    };
}

/// The descriptor of a library providing `plugins`, stamped with this SDK's versions.
pub const fn descriptor(plugins: &'static [PluginEntry]) -> Descriptor {
    Descriptor { abi_version: ABI_VERSION, core_version: RStr::new(CORE_VERSION), rustc_version: RStr::new(RUSTC_VERSION), n_plugins: plugins.len(), plugins: plugins.as_ptr() }
}

/// The table entry of criterion `T` named `name`.
pub const fn criterion_entry<T: Criterion>(name: &'static str) -> PluginEntry {
    PluginEntry { kind: KIND_CRITERION, name: RStr::new(name), create: shim::criterion_create::<T>, destroy: shim::destroy::<T>, check_batch: Some(shim::criterion_check::<T>), propose: None }
}

/// The table entry of separation rule `T` named `name`.
pub const fn separation_entry<T: Separation>(name: &'static str) -> PluginEntry {
    PluginEntry { kind: KIND_SEPARATION, name: RStr::new(name), create: shim::separation_create::<T>, destroy: shim::destroy::<T>, check_batch: None, propose: Some(shim::separation_propose::<T>) }
}

/// The C functions behind each entry. Public for the macro and the tests; not an API.
#[doc(hidden)]
pub mod shim {
    use super::*;

    /// An error for the host: (key, message).
    type Fail = (String, String);

    fn panic_text(p: &(dyn Any + Send)) -> String {
        match (p.downcast_ref::<&str>(), p.downcast_ref::<String>()) {
            (Some(s), _) => s.to_string(),
            (_, Some(s)) => s.clone(),
            _ => "(a panic without a message)".into(),
        }
    }

    /// Runs `f`, turning an error or a panic into a status and a message in `err`.
    fn guard(err: *mut ErrorOut, f: impl FnOnce() -> Result<i32, Fail>) -> i32 {
        let (st, key, msg) = match catch_unwind(AssertUnwindSafe(f)) {
            Ok(Ok(st)) => return st,
            Ok(Err((k, m))) => (STATUS_ERROR, k, m),
            Err(p) => (STATUS_PANIC, String::new(), panic_text(p.as_ref())),
        };
        // SAFETY: the host passes a valid ErrorOut (or null).
        if let Some(e) = unsafe { err.as_mut() } {
            e.set(&key, &msg);
        }
        st
    }

    /// Parses the parameter table; the key of an unknown, missing or ill-typed field is named.
    pub fn parse<T: DeserializeOwned>(json: &str) -> Result<T, Fail> {
        let de = &mut serde_json::Deserializer::from_str(json);
        serde_path_to_error::deserialize::<_, T>(de).map_err(|e| {
            let path = e.path().to_string();
            let mut msg = e.inner().to_string();
            if let Some(at) = msg.rfind(" at line ") {
                msg.truncate(at); // positions in the generated JSON mean nothing to the user
            }
            let named = ["unknown field `", "missing field `"].iter().find_map(|p| msg.strip_prefix(p).and_then(|r| r.split('`').next()).map(str::to_string));
            let key = if path != "." && !path.is_empty() { path } else { named.unwrap_or_default() };
            (key, msg)
        })
    }

    fn create<T: Send + Sync + DeserializeOwned>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut, validate: fn(&T) -> Result<(), ParamError>) -> i32 {
        guard(err, || {
            // SAFETY: the host passes the JSON text for the duration of the call.
            let json = unsafe { params.as_str() }.map_err(|e| (String::new(), format!("parameters are not UTF-8: {e}")))?;
            let v: T = parse(json)?;
            validate(&v).map_err(|e| (e.key, e.msg))?;
            if out.is_null() {
                return Err((String::new(), "null output pointer".into()));
            }
            // SAFETY: checked non-null; the host owns the slot.
            unsafe { *out = Box::into_raw(Box::new(v)) as *mut c_void };
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn criterion_create<T: Criterion>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        create::<T>(params, out, err, T::validate)
    }

    pub unsafe extern "C" fn separation_create<T: Separation>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        create::<T>(params, out, err, T::validate)
    }

    pub unsafe extern "C" fn destroy<T>(instance: *mut c_void) {
        if !instance.is_null() {
            // SAFETY: made by `create::<T>`, freed once by the host; a panicking Drop is swallowed.
            let _ = catch_unwind(AssertUnwindSafe(|| drop(unsafe { Box::from_raw(instance as *mut T) })));
        }
    }

    pub unsafe extern "C" fn criterion_check<T: Criterion>(instance: *const c_void, n: usize, p: *const CPrincipal, scale: *const f64, out: *mut CFailureCheck, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            if n == 0 {
                return Ok(STATUS_OK);
            }
            // SAFETY: the host passes an instance of T and n valid entries per buffer.
            let (t, p, scale, out) = unsafe { (&*(instance as *const T), std::slice::from_raw_parts(p, n), std::slice::from_raw_parts(scale, n), std::slice::from_raw_parts_mut(out, n)) };
            for i in 0..n {
                out[i] = t.check(&p[i].into(), scale[i]).into();
            }
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn separation_propose<T: Separation>(
        instance: *const c_void,
        fan: *const CFan,
        failure: *const CFailureCheck,
        out_edges: *mut u32,
        cap: usize,
        out_len: *mut usize,
        err: *mut ErrorOut,
    ) -> i32 {
        guard(err, || {
            // SAFETY: the host passes valid pointers for the duration of the call.
            let (t, cf, chk) = unsafe { (&*(instance as *const T), &*fan, *failure) };
            let raw = if cf.n_links == 0 { &[][..] } else { unsafe { std::slice::from_raw_parts(cf.links, cf.n_links) } };
            let links: Vec<LinkGeom> = raw.iter().map(|l| LinkGeom { edge: EdgeId(l.edge), angle: l.angle, normal: l.normal }).collect();
            let view =
                FanView { point: PointId(cf.point), cluster: ClusterId(cf.cluster), closed: cf.closed != 0, never_split: false, links: &links, stress: cf.stress, principal: cf.principal.into() };
            let chk = chk.to_check().map_err(|e| (String::new(), format!("host sent a bad failure check: {e}")))?;
            let Some(prop) = t.propose(&view, &chk) else { return Ok(STATUS_NONE) };
            if prop.edges.len() > cap {
                return Err((String::new(), format!("proposed {} edges for a fan of {} links", prop.edges.len(), cf.n_links)));
            }
            // SAFETY: the host gives `cap` slots and a valid length slot.
            unsafe {
                for (i, e) in prop.edges.iter().enumerate() {
                    *out_edges.add(i) = e.0;
                }
                *out_len = prop.edges.len();
            }
            Ok(STATUS_OK)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Strength {
        tensile_strength: f64,
        #[serde(default)]
        boom: bool,
    }

    impl Criterion for Strength {
        fn validate(&self) -> Result<(), ParamError> {
            ParamError::range("tensile_strength", self.tensile_strength, 0.0, false, f64::INFINITY, false)
        }
        fn check(&self, p: &Principal, _scale: f64) -> FailureCheck {
            assert!(!self.boom, "boom at s1 = {}", p.s1);
            FailureCheck { index: -p.s3 / self.tensile_strength, ..Default::default() }
        }
    }

    fn create(json: &str) -> (i32, *mut c_void, ErrorOut) {
        let mut err = ErrorOut::default();
        let mut out = std::ptr::null_mut();
        let st = unsafe { shim::criterion_create::<Strength>(RStr::new(json), &mut out, &mut err) };
        (st, out, err)
    }

    /// Bad parameters come back as errors naming the key: an unknown key, a missing key, a
    /// wrong type, and a value out of range (the plugin's `validate`). Exact messages.
    #[test]
    fn bad_parameters_name_the_key() {
        let (st, _, e) = create(r#"{"tensile_strength": 1.0, "cohesion": 2}"#);
        assert_eq!((st, e.key().as_str()), (STATUS_ERROR, "cohesion"), "{}", e.msg());
        assert!(e.msg().starts_with("unknown field `cohesion`"), "{}", e.msg());
        let (st, _, e) = create("{}");
        assert_eq!((st, e.key(), e.msg()), (STATUS_ERROR, "tensile_strength".into(), "missing field `tensile_strength`".into()));
        let (st, _, e) = create(r#"{"tensile_strength": "high"}"#);
        assert_eq!((st, e.key().as_str()), (STATUS_ERROR, "tensile_strength"));
        assert!(e.msg().starts_with("invalid type: string \"high\", expected f64"), "{}", e.msg());
        let (st, _, e) = create(r#"{"tensile_strength": -1.0}"#);
        assert_eq!((st, e.key(), e.msg()), (STATUS_ERROR, "tensile_strength".into(), "= -1 is incorrect; it must be in (0, inf)".into()));
    }

    /// A panic inside `check` is caught by the shim (status PANIC and its message), a good
    /// batch runs every point. Reference: the definitions above; exact.
    #[test]
    fn panics_are_caught_and_batches_run() {
        for (json, want) in [(r#"{"tensile_strength": 2.0}"#, STATUS_OK), (r#"{"tensile_strength": 2.0, "boom": true}"#, STATUS_PANIC)] {
            let (st, inst, _) = create(json);
            assert_eq!(st, STATUS_OK);
            let p = [CPrincipal { s1: 1.0, s3: -1.0, ..Default::default() }, CPrincipal { s1: 3.0, s3: -3.0, ..Default::default() }];
            let mut out = [CFailureCheck::default(); 2];
            let mut err = ErrorOut::default();
            let st = unsafe { shim::criterion_check::<Strength>(inst, 2, p.as_ptr(), [1.0, 1.0].as_ptr(), out.as_mut_ptr(), &mut err) };
            assert_eq!(st, want);
            if want == STATUS_OK {
                assert_eq!((out[0].index, out[1].index), (0.5, 1.5));
            } else {
                assert_eq!(err.msg(), "boom at s1 = 1");
            }
            unsafe { shim::destroy::<Strength>(inst) };
        }
    }
}
