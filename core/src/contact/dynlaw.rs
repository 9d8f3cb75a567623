//! Contact laws from a shared library (issue 25; the loader, ABI and SDK are
//! `crate::plugin::dynload`, docs/plugins.md): [`DynContact`] behind [`ContactLaw`], and the
//! `deserialize_with` of `[contact] law` ([`de_contact`]). It lives in this layer, not beside the
//! other dynamic wrappers, because the contact law trait does (core layering, tests/layout.rs).
//!
//! The pairs' history stays in the core's [`PairState`]: the law's `n_state` (<= 3) f64 are its
//! slots `en`, `es`, `max_open`, passed with a stride of 3. One C call per chunk of 256 pairs
//! (kinematics, history and forces converted on the stack, no allocation). A status other than
//! OK or a non-finite force or history records a fault naming the law and its library
//! ([`ContactLaw::fault`]) and returns NaN forces, which the divergence guard stops on.
use std::mem::MaybeUninit;

use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

use crate::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use crate::plugin::dynload::abi::{CPairForce, CPairKin, PluginEntry, KIND_CONTACT, STATUS_OK};
use crate::plugin::dynload::{self, call_fault, err_slot, read_err, Instance, PluginInfo, CHUNK};
use crate::plugin::traits::ParamError;

/// A contact law from a loaded library.
#[derive(Debug, Serialize)]
#[serde(transparent)]
pub struct DynContact(Instance);

impl DynContact {
    pub fn new(info: PluginInfo, entry: &'static PluginEntry, table: toml::Value) -> Self {
        DynContact(Instance::new(info, entry, table))
    }
    pub fn info(&self) -> &PluginInfo {
        &self.0.info
    }
}

/// Whether a built-in contact law has this name.
pub fn is_builtin(name: &str) -> bool {
    dynload::registry_has::<dyn ContactLaw>(name)
}

/// `deserialize_with` for `[contact] law`: a loaded plugin's name builds a [`DynContact`]
/// (refused when a built-in has the same name: the loader cannot see this layer's built-ins),
/// any other name goes to typetag.
pub fn de_contact<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Box<dyn ContactLaw>, D::Error> {
    let v = toml::Value::deserialize(d)?;
    if let Some((info, entry)) = v.get("type").and_then(|t| t.as_str()).and_then(|n| dynload::find_entry(KIND_CONTACT, n)) {
        if is_builtin(info.name) {
            return Err(D::Error::custom(format!("contact law \"{}\" of the plugin library {} has the name of a built-in contact law; rename it", info.name, info.file.display())));
        }
        return Ok(Box::new(DynContact::new(info, entry, v)));
    }
    Box::<dyn ContactLaw>::deserialize(v).map_err(|e| D::Error::custom(dynload::with_loaded_names(e.to_string(), KIND_CONTACT)))
}

impl ContactLaw for DynContact {
    dynload::instance_methods!();

    fn stiffness(&self) -> f64 {
        match (self.0.live(), self.0.entry.contact_stiffness) {
            // SAFETY: ABI call on a live instance.
            (Ok(p), Some(f)) => unsafe { f(p) },
            _ => f64::NAN,
        }
    }

    fn evaluate(&self, kin: &[PairKinematics], hist: &mut [PairState], out: &mut [PairForce]) {
        let ns = self.0.entry.n_state.min(3);
        let fail = |out: &mut [PairForce], msg: String| {
            self.0.record(msg);
            out.iter_mut().for_each(|o| *o = PairForce { normal: f64::NAN, tangential: f64::NAN, active: true, stored: f64::NAN, dissipated: f64::NAN, fracture: 0.0 });
        };
        let (inst, f) = match (self.0.live(), self.0.entry.contact_evaluate) {
            (Ok(p), Some(f)) => (p, f),
            (Err(e), _) => return fail(out, e),
            (_, None) => return fail(out, format!("{} has no contact_evaluate", self.0.who())),
        };
        let n = kin.len().min(hist.len()).min(out.len());
        let mut ck = [const { MaybeUninit::<CPairKin>::uninit() }; CHUNK];
        let mut cs = [0.0f64; CHUNK * 3];
        let mut co = [const { MaybeUninit::<CPairForce>::uninit() }; CHUNK];
        let mut start = 0;
        while start < n {
            let m = CHUNK.min(n - start);
            for i in 0..m {
                let (k, h) = (&kin[start + i], &hist[start + i]);
                ck[i].write(CPairKin { gap: k.gap, dgap: k.dgap, dslip: k.dslip, vn: k.vn, vs: k.vs, area: k.area, area_old: k.area_old, dt: k.dt, new: k.new as u32, fresh: h.fresh as u32 });
                (cs[3 * i], cs[3 * i + 1], cs[3 * i + 2]) = (h.en, h.es, h.max_open);
            }
            let mut err = err_slot();
            // SAFETY: ABI call with m kinematics, m x 3 state and m output slots.
            let st = unsafe { f(inst, m, ck.as_ptr().cast(), cs.as_mut_ptr(), co.as_mut_ptr().cast(), err.as_mut_ptr()) };
            if st != STATUS_OK {
                let (key, msg) = read_err(&err);
                return fail(out, call_fault(&self.0.who(), st, "contact_evaluate", &key, &msg));
            }
            for i in 0..m {
                // SAFETY: written by the plugin (STATUS_OK).
                let c = unsafe { co[i].assume_init() };
                let h = &mut hist[start + i];
                let slots = [cs[3 * i], cs[3 * i + 1], cs[3 * i + 2]];
                let sum = c.normal + c.tangential + c.stored + c.dissipated + slots[0] + slots[1] + slots[2];
                if !sum.is_finite() {
                    let k = &kin[start + i];
                    return fail(
                        out,
                        format!(
                            "{} returned a non-finite force or history for a pair (gap {:e}, dgap {:e}, dslip {:e}, area {:e}): force ({}, {}), stored {}, dissipated {}, history {:?}",
                            self.0.who(),
                            k.gap,
                            k.dgap,
                            k.dslip,
                            k.area,
                            c.normal,
                            c.tangential,
                            c.stored,
                            c.dissipated,
                            &slots[..ns]
                        ),
                    );
                }
                (h.en, h.es, h.max_open) = (slots[0], slots[1], slots[2]);
                out[start + i] = PairForce { normal: c.normal, tangential: c.tangential, active: c.active != 0, stored: c.stored, dissipated: c.dissipated, fracture: 0.0 };
            }
            start += m;
        }
    }

    fn fault(&self) -> Option<String> {
        self.0.fault.get().cloned()
    }
}
