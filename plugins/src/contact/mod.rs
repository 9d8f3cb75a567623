//! Contact laws (METHOD section 6; the paper's section 3.2, eqs. 10-17).
//!
//! What: each law turns the kinematics of a contact pair (signed gap, increments of the
//! relative displacement and relative velocity in the master face's frame, the slave's
//! tributary area) into a normal and a tangential force on the slave, and keeps the pair's
//! history ([`flem_core::contact::PairState`]). The core applies the force to the slave and,
//! with the opposite sign, to the face ends by the division ratio (eq. 16-17).
//!
//! Why several: `spring_dashpot` is the paper's incremental DEM law; `penalty` is a total-gap
//! law whose normal force is path independent (exactly conservative without friction or
//! dashpots); `cohesive` lets a freshly split face carry decaying tension first.
//!
//! Units: stiffnesses are **per unit contact area** (stress / length; a pair's spring is
//! `k x area`, `area` = tributary length x thickness of the slave, so a uniform pressure
//! gives a uniform penetration); dashpots per unit area (stress x time / length); strengths
//! in stress; fracture energy in energy / area. The paper's per-node springs (Table 1:
//! `k_n / (rho g) = 6210 cm^2`) are `k x area` here.
//!
//! Selected by `[contact] law = { type = "name", ... }`.
pub mod cohesive;
pub mod penalty;
pub mod spring_dashpot;

/// The registered contact-law names.
pub const NAMES: &[&str] = &["spring_dashpot", "penalty", "cohesive"];

/// Coulomb cap of a tangential spring force (paper eq. 13): returns (capped force, slipped).
pub(crate) fn coulomb_cap(es: f64, limit: f64) -> (f64, bool) {
    if es.abs() > limit {
        (limit.max(0.0) * es.signum(), true)
    } else {
        (es, false)
    }
}

/// Energy dissipated by a Coulomb slip in one step: the tangential spring went from `es_old` to
/// the trial `es_old - k_s A dslip` (`trial`, stiffness `ks = k_s A`) and was capped to `es`.
/// The ledger credits the step the trapezoid `1/2 (es_old + es) dslip` with
/// `dslip = (es_old - trial) / ks`; less the change of stored `es^2 / (2 ks)` this leaves
/// `(es_old + es)(trial - es) / (2 ks)` (the rectangle `|trial - es| |es| / ks` misses the
/// work done while the cap moves with the normal force).
pub(crate) fn slip_dissipation(es_old: f64, trial: f64, es: f64, ks: f64) -> f64 {
    0.5 * (es_old + es) * (trial - es) / ks
}

#[cfg(test)]
mod tests {
    use flem_core::contact::ContactLaw;

    const SOURCES: &[(&str, &str)] =
        &[("contact/spring_dashpot.rs", include_str!("spring_dashpot.rs")), ("contact/penalty.rs", include_str!("penalty.rs")), ("contact/cohesive.rs", include_str!("cohesive.rs"))];

    /// Every ```toml snippet in the docs parses as a `[contact] law` and validates; every name
    /// has one. Reference: the docs; exact.
    #[test]
    fn doc_toml_snippets_parse_and_validate() {
        for (file, law) in crate::snippets::doc_snippets::<Box<dyn ContactLaw>>(SOURCES, &["contact", "law"], super::NAMES) {
            law.validate().unwrap_or_else(|e| panic!("{file}: {e}"));
            assert!(law.stiffness() > 0.0, "{file}");
        }
    }
}
