//! `flem-plugin-sdk`: write a FLEM failure criterion, separation rule, contact law, damping
//! scheme or material law (a UMAT of FLEM) in your own crate, build it as a shared library
//! (`crate-type = ["cdylib"]`) and load it from a scene with
//! `[plugins] load = ["path/to/libyours.so"]`, without rebuilding FLEM.
//!
//! A plugin author writes one trait impl ([`Criterion`], [`Separation`], [`Contact`],
//! [`DampingScheme`], or [`Law`] with its [`BoundLaw`]) on a `serde::Deserialize` parameter
//! struct, and one registration line:
//!
//! ```ignore
//! flem_plugin_sdk::export_plugins!(criterion "my_rankine" => MyRankine, material "my_law" => MyLaw);
//! ```
//!
//! State that a contact law, damping scheme or material law keeps (its `STATE` f64 per pair,
//! per scheme, per integration point) is handed to each call as a `&mut [f64]` that the core
//! owns: checkpoints, resume and threads need nothing from the plugin, and the plugin's own
//! structs stay immutable after they are made.
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

pub use flem_core::contact::{PairForce, PairKinematics};
pub use flem_core::element::{Dmat, Material, Plane};
pub use flem_core::ids::{ClusterId, EdgeId, PointId};
pub use flem_core::plugin::damping::{DampingCoeffs, StepStats};
pub use flem_core::plugin::dynload::abi;
pub use flem_core::plugin::traits::{line_angle, principal, ray_angle, FailureCheck, FailureMode, FanView, LinkGeom, ParamError, Principal, Proposal};
pub use serde;

use abi::{
    CDampingCoeffs, CDampingInfo, CFailureCheck, CFan, CMaterial, CPairForce, CPairKin, CPrincipal, CStepStats, Descriptor, ErrorOut, PluginEntry, RStr, ABI_VERSION, CONTACT_STATE_MAX, CORE_VERSION,
    KIND_CONTACT, KIND_CRITERION, KIND_DAMPING, KIND_MATERIAL, KIND_SEPARATION, RUSTC_VERSION, STATUS_ERROR, STATUS_NONE, STATUS_OK, STATUS_PANIC,
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

/// A contact law (the dynamic twin of [`flem_core::contact::ContactLaw`]), one pair per call of
/// `evaluate` (the shim loops over the batch, monomorphised).
pub trait Contact: DeserializeOwned + Send + Sync + 'static {
    /// f64 of history per pair, at most 3. The core keeps them in the pair's `PairState`
    /// (`en`, `es`, `max_open`): slots 0 and 1 are read as the normal and tangential spring
    /// forces, which the core scales by `sqrt(A_new / A_old)` when a split changes the area.
    const STATE: usize;
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    /// The largest spring stiffness per unit area (stress / length), for the stable step.
    fn stiffness(&self) -> f64;
    /// The force on the slave of one pair; updates its history `state` (`STATE` f64, zeros for
    /// a pair never seen). `fresh`: the pair joins the faces of an edge split during the run.
    fn evaluate(&self, kin: &PairKinematics, fresh: bool, state: &mut [f64]) -> PairForce;
}

/// A damping scheme (the dynamic twin of [`flem_core::plugin::damping::Damping`]).
pub trait DampingScheme: DeserializeOwned + Send + Sync + 'static {
    /// f64 of state (checkpointed by the core).
    const STATE: usize = 0;
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    /// Start of a stage.
    fn reset(&self, _state: &mut [f64]) {}
    /// Coefficients of the next step from the statistics of the last one.
    fn coeffs(&self, stats: &StepStats, state: &mut [f64]) -> DampingCoeffs;
    /// Whether `coeffs` reads `u_f_int` and `u_m_u` (the solver then sums them every step).
    fn uses_rayleigh_stats(&self) -> bool {
        true
    }
    /// Factor (<= 1) on the critical time step.
    fn stability_factor(&self) -> f64 {
        1.0
    }
}

/// A material law's parameters (the dynamic twin of [`flem_core::element::law::LawCfg`]):
/// `bind` makes the law of one region from them and the region's elastic material.
pub trait Law: DeserializeOwned + Send + Sync + 'static {
    /// f64 of history per integration point (zeros at the start).
    const STATE: usize;
    /// The law of a region; the error names the key (relative to `law`).
    type Bound: BoundLaw;
    fn bind(&self, mat: &Material) -> Result<Self::Bound, ParamError>;
}

/// A material law bound to a region (the dynamic twin of
/// [`flem_core::element::law::MaterialLaw`]). Conventions: stress `[sxx, syy, sxy, szz]`
/// tension positive, strain increment `[dexx, deyy, dgxy, dezz]` (engineering shear).
pub trait BoundLaw: Send + Sync + 'static {
    /// Elastic moduli (stable step, implicit check, initial tangent).
    fn elastic(&self) -> Dmat;
    /// Stress update of one point, in place; `state` its `STATE` f64 of history.
    fn update(&self, stress: &mut [f64; 4], deps: [f64; 4], state: &mut [f64]);
    /// `(plastic shear strain, state 0 never / 1 last update / 2 past)` for the output.
    fn output(&self, _state: &[f64]) -> (f64, u8) {
        (0.0, 0)
    }
}

/// Exports the plugins of this library: `kind "name" => Type`, with kind `criterion`,
/// `separation`, `contact`, `damping` or `material`. Use it once per library.
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
    (contact $name:literal $ty:ty) => {
        $crate::contact_entry::<$ty>($name)
    };
    (damping $name:literal $ty:ty) => {
        $crate::damping_entry::<$ty>($name)
    };
    (material $name:literal $ty:ty) => {
        $crate::material_entry::<$ty>($name)
    };
}

/// The descriptor of a library providing `plugins`, stamped with this SDK's versions.
pub const fn descriptor(plugins: &'static [PluginEntry]) -> Descriptor {
    Descriptor { abi_version: ABI_VERSION, core_version: RStr::new(CORE_VERSION), rustc_version: RStr::new(RUSTC_VERSION), n_plugins: plugins.len(), plugins: plugins.as_ptr() }
}

/// The table entry of criterion `T` named `name`.
pub const fn criterion_entry<T: Criterion>(name: &'static str) -> PluginEntry {
    PluginEntry { check_batch: Some(shim::criterion_check::<T>), ..PluginEntry::empty(KIND_CRITERION, name, shim::criterion_create::<T>, shim::destroy::<T>) }
}

/// The table entry of separation rule `T` named `name`.
pub const fn separation_entry<T: Separation>(name: &'static str) -> PluginEntry {
    PluginEntry { propose: Some(shim::separation_propose::<T>), ..PluginEntry::empty(KIND_SEPARATION, name, shim::separation_create::<T>, shim::destroy::<T>) }
}

/// The table entry of contact law `T` named `name`.
pub const fn contact_entry<T: Contact>(name: &'static str) -> PluginEntry {
    assert!(T::STATE <= CONTACT_STATE_MAX, "a contact law keeps at most 3 f64 per pair");
    PluginEntry {
        n_state: T::STATE,
        contact_stiffness: Some(shim::contact_stiffness::<T>),
        contact_evaluate: Some(shim::contact_evaluate::<T>),
        ..PluginEntry::empty(KIND_CONTACT, name, shim::contact_create::<T>, shim::destroy::<T>)
    }
}

/// The table entry of damping scheme `T` named `name`.
pub const fn damping_entry<T: DampingScheme>(name: &'static str) -> PluginEntry {
    PluginEntry {
        n_state: T::STATE,
        damping_info: Some(shim::damping_info::<T>),
        damping_reset: Some(shim::damping_reset::<T>),
        damping_coeffs: Some(shim::damping_coeffs::<T>),
        ..PluginEntry::empty(KIND_DAMPING, name, shim::damping_create::<T>, shim::destroy::<T>)
    }
}

/// The table entry of material law `T` named `name`.
pub const fn material_entry<T: Law>(name: &'static str) -> PluginEntry {
    PluginEntry {
        n_state: T::STATE,
        law_bind: Some(shim::law_bind::<T>),
        law_destroy: Some(shim::destroy::<T::Bound>),
        law_elastic: Some(shim::law_elastic::<T>),
        law_update: Some(shim::law_update::<T>),
        law_output: Some(shim::law_output::<T>),
        ..PluginEntry::empty(KIND_MATERIAL, name, shim::material_create::<T>, shim::destroy::<T>)
    }
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
        // SAFETY: the host passes a valid ErrorOut (or null); written through raw pointers.
        unsafe { abi::write_err(err, &key, &msg) };
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

    pub unsafe extern "C" fn contact_create<T: Contact>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        create::<T>(params, out, err, T::validate)
    }

    pub unsafe extern "C" fn damping_create<T: DampingScheme>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        create::<T>(params, out, err, T::validate)
    }

    pub unsafe extern "C" fn material_create<T: Law>(params: RStr, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        create::<T>(params, out, err, |_| Ok(()))
    }

    pub unsafe extern "C" fn contact_stiffness<T: Contact>(instance: *const c_void) -> f64 {
        // SAFETY: the host passes an instance of T.
        catch_unwind(AssertUnwindSafe(|| unsafe { &*(instance as *const T) }.stiffness())).unwrap_or(f64::NAN)
    }

    pub unsafe extern "C" fn contact_evaluate<T: Contact>(instance: *const c_void, n: usize, kin: *const CPairKin, state: *mut f64, out: *mut CPairForce, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            if n == 0 {
                return Ok(STATUS_OK);
            }
            // SAFETY: the host passes an instance of T, n kinematics, 3 n state, n outputs.
            let (t, kin, out) = unsafe { (&*(instance as *const T), std::slice::from_raw_parts(kin, n), std::slice::from_raw_parts_mut(out, n)) };
            // Stride CONTACT_STATE_MAX (the core's PairState slots), the first STATE the law's.
            let state: &mut [f64] = unsafe { std::slice::from_raw_parts_mut(state, n * CONTACT_STATE_MAX) };
            for i in 0..n {
                let c = &kin[i];
                let k = PairKinematics { gap: c.gap, dgap: c.dgap, dslip: c.dslip, vn: c.vn, vs: c.vs, area: c.area, area_old: c.area_old, dt: c.dt, new: c.new != 0 };
                let f = t.evaluate(&k, c.fresh != 0, &mut state[i * CONTACT_STATE_MAX..i * CONTACT_STATE_MAX + T::STATE]);
                out[i] = CPairForce { normal: f.normal, tangential: f.tangential, stored: f.stored, dissipated: f.dissipated, active: f.active as u32 };
            }
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn damping_info<T: DampingScheme>(instance: *const c_void, out: *mut CDampingInfo) {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the host passes an instance of T and an output slot.
            let t = unsafe { &*(instance as *const T) };
            unsafe { *out = CDampingInfo { uses_rayleigh_stats: t.uses_rayleigh_stats() as u32, stability_factor: t.stability_factor() } };
        }));
    }

    fn state_slice<'a>(state: *mut f64, n: usize) -> &'a mut [f64] {
        if n == 0 {
            &mut []
        } else {
            // SAFETY: the host passes n state slots for the duration of the call.
            unsafe { std::slice::from_raw_parts_mut(state, n) }
        }
    }

    pub unsafe extern "C" fn damping_reset<T: DampingScheme>(instance: *const c_void, state: *mut f64, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            // SAFETY: the host passes an instance of T.
            unsafe { &*(instance as *const T) }.reset(state_slice(state, T::STATE));
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn damping_coeffs<T: DampingScheme>(instance: *const c_void, stats: *const CStepStats, state: *mut f64, out: *mut CDampingCoeffs, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            // SAFETY: the host passes an instance of T and valid pointers.
            let (t, s) = unsafe { (&*(instance as *const T), *stats) };
            let st = StepStats { step: s.step, dt: s.dt, omega_max: s.omega_max, kinetic: s.kinetic, u_f_int: s.u_f_int, u_m_u: s.u_m_u };
            let c = t.coeffs(&st, state_slice(state, T::STATE));
            unsafe { *out = CDampingCoeffs { viscous: c.viscous, local: c.local, eta: c.eta } };
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn law_bind<T: Law>(instance: *const c_void, mat: *const CMaterial, out: *mut *mut c_void, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            // SAFETY: the host passes an instance of T and a material.
            let (t, m) = unsafe { (&*(instance as *const T), *mat) };
            let law = t.bind(&Material::from(m)).map_err(|e| (e.key, e.msg))?;
            if out.is_null() {
                return Err((String::new(), "null output pointer".into()));
            }
            // SAFETY: checked non-null; the host owns the slot.
            unsafe { *out = Box::into_raw(Box::new(law)) as *mut c_void };
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn law_elastic<T: Law>(law: *const c_void, out: *mut f64) {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the host passes a law of T::Bound and 3 slots.
            let d = unsafe { &*(law as *const T::Bound) }.elastic();
            unsafe { std::ptr::copy_nonoverlapping([d.d11, d.d12, d.d33].as_ptr(), out, 3) };
        }));
    }

    /// The stress update of one point: called once per Gauss point per step (the hot path).
    #[inline]
    pub unsafe extern "C" fn law_update<T: Law>(law: *const c_void, stress: *mut f64, deps: *const f64, state: *mut f64, err: *mut ErrorOut) -> i32 {
        guard(err, || {
            // SAFETY: the host passes a law of T::Bound, 4 stress slots, 4 increments and STATE
            // history slots, for the duration of the call.
            let (l, s, de) = unsafe { (&*(law as *const T::Bound), &mut *(stress as *mut [f64; 4]), *(deps as *const [f64; 4])) };
            l.update(s, de, state_slice(state, T::STATE));
            Ok(STATUS_OK)
        })
    }

    pub unsafe extern "C" fn law_output<T: Law>(law: *const c_void, state: *const f64, gamma: *mut f64, flag: *mut u8) {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: as law_update; the state is read only.
            let l = unsafe { &*(law as *const T::Bound) };
            let (g, f) = l.output(state_slice(state as *mut f64, T::STATE));
            unsafe { (*gamma, *flag) = (g, f) };
        }));
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
            let view = FanView {
                point: PointId(cf.point),
                cluster: ClusterId(cf.cluster),
                closed: cf.closed != 0,
                never_split: cf.never_split != 0,
                links: &links,
                stress: cf.stress,
                principal: cf.principal.into(),
            };
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
    /// A contact law with one f64 of history: the shim reads and writes pair i's history at
    /// `3 i` (the core's stride), converts the kinematics and forces, and runs every pair.
    #[derive(Deserialize)]
    struct Counter {}
    impl Contact for Counter {
        const STATE: usize = 1;
        fn stiffness(&self) -> f64 {
            2.0
        }
        fn evaluate(&self, k: &PairKinematics, fresh: bool, state: &mut [f64]) -> PairForce {
            state[0] += 1.0;
            PairForce { normal: k.gap * 10.0 + fresh as u8 as f64, tangential: state[0], active: !k.new, stored: 0.0, dissipated: 0.0, fracture: 0.0 }
        }
    }

    /// Reference: the definitions above; exact.
    #[test]
    fn contact_shim_uses_the_core_stride() {
        let kin = [CPairKin { gap: 1.0, ..Default::default() }, CPairKin { gap: 2.0, new: 1, fresh: 1, ..Default::default() }];
        let mut state = [5.0, 7.0, 9.0, 10.0, 70.0, 90.0];
        let mut out = [CPairForce::default(); 2];
        let mut err = ErrorOut::default();
        let t = Counter {};
        let st = unsafe { shim::contact_evaluate::<Counter>(&t as *const Counter as *const c_void, 2, kin.as_ptr(), state.as_mut_ptr(), out.as_mut_ptr(), &mut err) };
        assert_eq!(st, STATUS_OK);
        assert_eq!(state, [6.0, 7.0, 9.0, 11.0, 70.0, 90.0]);
        assert_eq!((out[0].normal, out[0].tangential, out[0].active), (10.0, 6.0, 1));
        assert_eq!((out[1].normal, out[1].tangential, out[1].active), (21.0, 11.0, 0));
    }

    /// A material law whose update panics: the shim returns PANIC with the message.
    #[derive(Deserialize)]
    struct Boom {}
    struct BoomLaw;
    impl Law for Boom {
        const STATE: usize = 0;
        type Bound = BoomLaw;
        fn bind(&self, _m: &Material) -> Result<BoomLaw, ParamError> {
            Ok(BoomLaw)
        }
    }
    impl BoundLaw for BoomLaw {
        fn elastic(&self) -> Dmat {
            Dmat { d11: 1.0, d12: 0.0, d33: 0.5 }
        }
        fn update(&self, s: &mut [f64; 4], _de: [f64; 4], _st: &mut [f64]) {
            panic!("boom at sxx = {}", s[0])
        }
    }

    #[test]
    fn material_update_panics_are_caught() {
        let law = BoomLaw;
        let mut s = [3.0, 0.0, 0.0, 0.0];
        let mut e = ErrorOut::default();
        let st = unsafe { shim::law_update::<Boom>(&law as *const BoomLaw as *const c_void, s.as_mut_ptr(), [0.0; 4].as_ptr(), std::ptr::NonNull::dangling().as_ptr(), &mut e) };
        assert_eq!(st, STATUS_PANIC);
        assert_eq!(e.msg(), "boom at sxx = 3");
    }
}
