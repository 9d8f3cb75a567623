//! `example_spring_dashpot` (contact law): a copy of the built-in `spring_dashpot`
//! (`plugins/src/contact/spring_dashpot.rs`), the paper's incremental linear spring-dashpot with
//! Coulomb slip and no tension (eqs. 10-14; METHOD section 6), loaded at run time. The same
//! arithmetic in the same order, so that tests/dynkinds.rs can compare it with the built-in bit
//! for bit on the direct shear box.
//!
//! Per pair (area `A`; history `state = [e_n, e_s]`, kept by the core in the pair's
//! `PairState`):
//! - springs (eq. 10-11): `e_n += -k_n A dgap`, `e_s += -k_s A dslip`; on a pair's first step
//!   `e_n = k_n A max(-gap, 0)`, `e_s = 0`;
//! - dashpots (eq. 12): `d_n = -eta_n A v_n`, `d_s = -eta_s A v_s`;
//! - no tension: `e_n <= 0` opens the pair; the normal force `max(e_n + d_n, 0)`;
//! - Coulomb slip (eq. 13-14): `|e_s + d_s| > mu N` gives `e_s = mu N sign(e_s + d_s)`, `d_s = 0`,
//!   with the slip dissipation `(e_s,old + e_s)(e_s* - e_s) / (2 k_s A)`.
//!
//! Units: stiffnesses stress/length (per unit area), dashpots stress x time / length,
//! `friction` dimensionless.
//!
//! ```toml
//! [contact]
//! law = { type = "example_spring_dashpot", normal_stiffness = 8.06e6, shear_stiffness = 2.015e6, friction = 0.577 }
//! ```
use flem_plugin_sdk::{Contact, PairForce, PairKinematics, ParamError};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleSpringDashpot {
    pub normal_stiffness: f64,
    pub shear_stiffness: f64,
    #[serde(default)]
    pub normal_damping: f64,
    #[serde(default)]
    pub shear_damping: f64,
    #[serde(default)]
    pub friction: f64,
    /// Tests only (tests/dynkinds.rs): the `nan_after`-th evaluation (counted over all pairs)
    /// returns a NaN normal force, to show that a contact law returning NaN stops the run with
    /// its name. Absent: never.
    #[serde(default)]
    pub nan_after: Option<u64>,
    #[serde(skip)]
    evaluations: std::sync::atomic::AtomicU64,
}

/// Coulomb cap of a tangential spring force (paper eq. 13): (capped force, slipped).
fn coulomb_cap(es: f64, limit: f64) -> (f64, bool) {
    if es.abs() > limit {
        (limit.max(0.0) * es.signum(), true)
    } else {
        (es, false)
    }
}

fn slip_dissipation(es_old: f64, trial: f64, es: f64, ks: f64) -> f64 {
    0.5 * (es_old + es) * (trial - es) / ks
}

impl Contact for ExampleSpringDashpot {
    /// `[e_n, e_s]`.
    const STATE: usize = 2;

    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("normal_stiffness", self.normal_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("shear_stiffness", self.shear_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("normal_damping", self.normal_damping, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("shear_damping", self.shear_damping, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction", self.friction, 0.0, true, f64::INFINITY, false)
    }

    fn stiffness(&self) -> f64 {
        self.normal_stiffness.max(self.shear_stiffness)
    }

    fn evaluate(&self, k: &PairKinematics, _fresh: bool, h: &mut [f64]) -> PairForce {
        if let Some(n) = self.nan_after {
            if self.evaluations.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1 >= n {
                return PairForce { normal: f64::NAN, active: true, ..PairForce::default() };
            }
        }
        let (kn, ks) = (self.normal_stiffness * k.area, self.shear_stiffness * k.area);
        let es_old = if k.new { 0.0 } else { h[1] };
        if k.new {
            h[0] = kn * (-k.gap).max(0.0);
            h[1] = 0.0;
        } else {
            h[0] -= kn * k.dgap;
            h[1] -= ks * k.dslip;
        }
        if h[0] <= 0.0 {
            return PairForce::default();
        }
        let dn = -self.normal_damping * k.area * k.vn;
        let mut ds = -self.shear_damping * k.area * k.vs;
        let normal = (h[0] + dn).max(0.0);
        let trial = h[1] + ds;
        let (capped, slipped) = coulomb_cap(trial, self.friction * normal);
        let mut diss = 0.0;
        if slipped {
            diss += slip_dissipation(es_old, h[1], capped, ks);
            h[1] = capped;
            ds = 0.0;
        }
        diss += -((normal - h[0]) * k.vn + ds * k.vs) * k.dt;
        PairForce { normal, tangential: h[1] + ds, active: true, stored: 0.5 * h[0] * h[0] / kn + 0.5 * h[1] * h[1] / ks, dissipated: diss, fracture: 0.0 }
    }
}
