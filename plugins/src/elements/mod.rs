//! Element kinds (the element trait: `flem_core::element::kernel::Blocked`; the registry:
//! `flem_core::element::registry`; docs/elements.md). Each file is one element and one
//! `inventory::submit!` registration line, chosen by `[[material]] element = "name"`; `q4` and
//! `t3` are the defaults of their cell types (the paper's elements).
pub mod q4;
pub mod q4_closed;
pub mod qm6;
pub mod t3;

pub use q4::Q4;
pub use q4_closed::Q4Closed;
pub use qm6::Qm6;
pub use t3::T3;

use flem_core::element::block::Block;
use flem_core::element::kernel::Blocked;
use flem_core::element::law::{MaterialLaw, RegionElems, StatefulOpts};
use flem_core::element::registry::stateful_block;
use flem_core::element::Material;
use flem_core::mesh::CellKind;

/// The stateful blocks of a region for a law defined in a plugin (what its `LawCfg::build`
/// calls): one block per element kind present, monomorphised per (kind, law). The kinds known
/// here are the built-ins with a stateful kernel (`q4` with B-bar, and `q4_closed` as `q4`, `t3`, `qm6`); a kind without one
/// builds nothing, and `Model::new` then refuses the scene naming `material[i].element`. (The
/// linear elastic law, a core law, reaches every kind through its registration instead:
/// `ElementKind::stateful_elastic`.)
pub fn build_stateful<L: MaterialLaw>(law: L, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>> {
    let mut out = Vec::new();
    for cell in [CellKind::Q4, CellKind::T3] {
        let b = match elems.kind_of(cell) {
            k if k == <Q4 as Blocked<4>>::NAME => stateful_block::<Q4, L, 4>(law.clone(), region, mat, opts, elems),
            // A stateful block has no elastic force kernel: `q4_closed` is `q4` there.
            k if k == <Q4Closed as Blocked<4>>::NAME => stateful_block::<Q4, L, 4>(law.clone(), region, mat, opts, elems),
            k if k == <T3 as Blocked<3>>::NAME => stateful_block::<T3, L, 3>(law.clone(), region, mat, opts, elems),
            k if k == <qm6::Qm6 as Blocked<4>>::NAME => qm6::stateful::<L>(law.clone(), region, mat, opts, elems),
            _ => None,
        };
        out.extend(b);
    }
    out
}

// A material law from a plugin library (core's `DynLaw`) gets its blocks here too.
inventory::submit! { flem_core::plugin::dynload::DynLawBlocks(build_stateful::<flem_core::plugin::dynload::DynLaw>) }

/// The integrand at one Gauss point: strain from the displacement derivatives along the
/// parent axes, stress, and the stress pulled back to the parent axes (unscaled by 1/det J,
/// which cancels against the Gauss weight's det J): `(P_x,s, P_x,e, P_y,s, P_y,e)`.
#[inline(always)]
pub(crate) fn parent_stress(j: [f64; 4], inv: f64, du: [f64; 4], d: &[f64; 3]) -> (f64, f64, f64, f64) {
    let [d11, d12, d33] = *d;
    let [exx, eyy, gxy] = parent_strain(j, inv, du);
    pull_back(j, d11 * exx + d12 * eyy, d12 * exx + d11 * eyy, d33 * gxy)
}

/// The strain `[exx, eyy, gxy]` of a point from the Jacobian `j = [j11, j12, j21, j22]`, its
/// `1 / det J` and the parent derivatives of u (`adj J grad_xi u / det J`).
#[inline(always)]
pub(crate) fn parent_strain(j: [f64; 4], inv: f64, du: [f64; 4]) -> [f64; 3] {
    let [j11, j12, j21, j22] = j;
    let [uxs, uxe, uys, uye] = du;
    [inv * (j22 * uxs - j12 * uxe), inv * (j11 * uye - j21 * uys), inv * ((j22 * uys - j12 * uye) + (j11 * uxe - j21 * uxs))]
}

/// `adj J^T sigma`: the stress pulled back to the parent axes, `(P_x,s, P_x,e, P_y,s, P_y,e)`.
#[inline(always)]
pub(crate) fn pull_back(j: [f64; 4], sxx: f64, syy: f64, sxy: f64) -> (f64, f64, f64, f64) {
    let [j11, j12, j21, j22] = j;
    (j22 * sxx - j21 * sxy, j11 * sxy - j12 * sxx, j22 * sxy - j21 * syy, j11 * syy - j12 * sxy)
}

#[cfg(test)]
mod tests;
