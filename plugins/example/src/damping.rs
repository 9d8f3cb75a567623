//! `example_adaptive` (damping): a copy of the built-in `adaptive` (`plugins/src/damping/mod.rs`),
//! adaptive dynamic relaxation (Underwood 1983; METHOD section 7), loaded at run time: critical
//! viscous damping of the current lowest mode, `alpha = 2 w0` with
//! `w0^2 = (u . F_int) / (u . M u)` (the Rayleigh quotient of the current displacement, free
//! dofs), `w0 <= w_max`; before the body has moved `w0 = w_max / 100`. `alpha` (1/time) is the
//! scheme's one f64 of state, kept by the core (checkpointed); no parameter.
//!
//! ```toml
//! [solver.damping]
//! type = "example_adaptive"
//! ```
use flem_plugin_sdk::{DampingCoeffs, DampingScheme, StepStats};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleAdaptive {
    /// Tests only (tests/dynkinds.rs): from step `nan_after` on the coefficients are NaN, to
    /// show that a damping scheme returning NaN stops the run with its name. Absent: never.
    #[serde(default)]
    pub nan_after: Option<u64>,
}

impl DampingScheme for ExampleAdaptive {
    /// `[alpha]`.
    const STATE: usize = 1;

    fn reset(&self, state: &mut [f64]) {
        state[0] = 0.0;
    }

    fn coeffs(&self, s: &StepStats, state: &mut [f64]) -> DampingCoeffs {
        let w2 = if s.u_m_u > 0.0 { s.u_f_int / s.u_m_u } else { 0.0 };
        let w0 = if w2 > 0.0 && w2.is_finite() { w2.sqrt().min(s.omega_max) } else { 0.01 * s.omega_max };
        state[0] = 2.0 * w0;
        if self.nan_after.is_some_and(|n| s.step >= n) {
            return DampingCoeffs { viscous: f64::NAN, ..Default::default() };
        }
        DampingCoeffs { viscous: state[0], ..Default::default() }
    }
}
