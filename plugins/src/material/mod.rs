//! Material laws (`[[material]] law = { type = "..." }`; the traits are
//! `flem_core::element::law::{LawCfg, MaterialLaw}`).
//!
//! What: a law updates the stress of an integration point from its strain increment and keeps
//! its history (plasticity). The linear elastic law is the default and keeps the stateless
//! blocked kernel; any other law (or `[solver] large_strain = true`) runs in a stateful block
//! (`flem_core::element::stateful`: per-point stress and history, B-bar on Q4).
//!
//! Built-ins: `linear_elastic` (in core: `flem_core::element::model::LinearElasticCfg`),
//! `mohr_coulomb` (this folder). docs/materials.md has the equations and the verification.
pub mod mohr_coulomb;

/// The registered law names (typetag `type = "..."`), in documentation order.
pub const NAMES: &[&str] = &["linear_elastic", "mohr_coulomb"];

#[cfg(test)]
mod tests {
    use flem_core::element::{Material, Plane};
    use flem_core::scene::MaterialCfg;

    const SOURCES: &[(&str, &str)] = &[("mohr_coulomb.rs", include_str!("mohr_coulomb.rs")), ("mohr_coulomb_softening.rs", include_str!("mohr_coulomb_softening.rs"))];

    /// Every ```toml snippet of the law docs parses as a `[[material]]` and its law validates.
    #[test]
    fn doc_toml_snippets_parse_and_validate() {
        let mut n = 0;
        for (file, src) in SOURCES {
            for b in crate::snippets::toml_blocks(src) {
                let t: toml::Table = toml::from_str(&b).unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
                let mats = t.get("material").and_then(|m| m.as_array()).unwrap_or_else(|| panic!("{file}: no [[material]] in\n{b}"));
                for m in mats {
                    let cfg: MaterialCfg = m.clone().try_into().unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
                    let law = cfg.law.as_ref().unwrap_or_else(|| panic!("{file}: snippet without a law"));
                    let mat = Material { young: cfg.young_modulus, poisson: cfg.poisson_ratio, density: cfg.density, thickness: cfg.thickness, plane: Plane::Strain };
                    law.validate(&mat).unwrap_or_else(|e| panic!("{file}: {e:?}"));
                    n += 1;
                }
            }
        }
        assert!(n >= 2);
    }
}
