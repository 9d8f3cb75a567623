//! `flem-plugin-example`: a FLEM plugin library loaded at run time (docs/plugins.md walks
//! through it). Built as a `cdylib` and never linked into `flem`:
//!
//! ```sh
//! cargo build --release -p flem-plugin-example    # -> target/release/libflem_plugin_example.so
//! ```
//!
//! It provides
//! - `example_rankine` (criterion): the Rankine maximum-tensile-stress criterion (METHOD
//!   section 4; the tension cut-off of the paper's eq. (1) on its own), the same arithmetic as
//!   the built-in `rankine`, so that tests/dynplug.rs can compare the two bit for bit;
//! - `example_sigma1_nearest` (separation): the paper's rule (paper section 2.2, figs. 3-5;
//!   METHOD section 5), the same choices as the built-in `sigma1_nearest`;
//! - `example_panic` (criterion): panics on purpose (in `create` or in `check`), to show that a
//!   plugin panic becomes an error of the run, never an abort;
//! - `example_spring_dashpot` (contact law, [`contact`]): the paper's law, a copy of the
//!   built-in `spring_dashpot`;
//! - `example_adaptive` (damping, [`damping`]): a copy of the built-in `adaptive`;
//! - `example_mohr_coulomb` (material law, [`material`]): a copy of the built-in `mohr_coulomb`;
//!   and `example_nan_law`, which returns NaN on purpose.
//!
//! A scene loads the library and names the plugins as it would a built-in (paths relative to
//! the scene file):
//!
//! ```toml
//! [plugins]
//! load = ["../target/release/libflem_plugin_example.so"]
//!
//! [cracking.criterion]
//! type = "example_rankine"
//! tensile_strength = 1.0    # stress units, > 0
//!
//! [cracking.separation]
//! type = "example_sigma1_nearest"
//! ```
pub mod contact;
pub mod damping;
pub mod material;

use std::f64::consts::{FRAC_PI_2, PI};

use flem_plugin_sdk::{line_angle, ray_angle, Criterion, EdgeId, FailureCheck, FailureMode, FanView, LinkGeom, ParamError, Principal, Proposal, Separation};
use serde::Deserialize;

/// Rankine: fails when the most tensile principal stress reaches the tensile strength.
/// Compression positive: fails when `s3 <= -sigma_t * scale`; index `-s3 / (sigma_t scale)`
/// clamped to [0, 1e6]; one failure plane along the sigma1 direction `theta1`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleRankine {
    /// Tensile strength sigma_t (stress), > 0.
    pub tensile_strength: f64,
}

impl Criterion for ExampleRankine {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("tensile_strength", self.tensile_strength, 0.0, false, f64::INFINITY, false)
    }

    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let st = self.tensile_strength * scale;
        let index = -p.s3 / st;
        if p.s3 <= -st {
            FailureCheck { index: clamp_index(index), mode: Some(FailureMode::Tension), planes: [wrap_pi(p.theta1), 0.0], n_planes: 1 }
        } else {
            FailureCheck { index: clamp_index(index), mode: None, planes: [0.0, 0.0], n_planes: 0 }
        }
    }
}

/// Failure index clamped to [0, 1e6]; NaN gives 0 (as the built-ins).
fn clamp_index(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1e6)
    }
}

/// An angle wrapped to [0, pi).
fn wrap_pi(a: f64) -> f64 {
    let r = a.rem_euclid(PI);
    if r >= PI {
        0.0
    } else {
        r
    }
}

/// The paper's separation rule: cut along the sigma1 direction `d = theta1`. Closed fan: the
/// link whose ray is nearest `d`, then among the others the one nearest `d + pi`. Open fan: the
/// link nearest `d` as a line, only if within pi/4 at a point that has split already (a point
/// never split, `FanView::never_split`, is cut whatever the angle: the paper's rule, METHOD 5).
/// Ties (1e-9 rad): counter-clockwise from the target first, then the smaller edge id. No
/// parameters.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleSigma1Nearest {}

const TIE: f64 = 1e-9;

/// The best link by (distance, then counter-clockwise, then edge id) among `cands`
/// of (distance, ccw, edge, link index).
fn pick(cands: impl Iterator<Item = (f64, bool, EdgeId, usize)> + Clone) -> Option<(f64, usize)> {
    let best = cands.clone().map(|c| c.0).filter(|d| !d.is_nan()).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return None;
    }
    cands.filter(|c| c.0 <= best + TIE).min_by_key(|c| (!c.1, c.2, c.3)).map(|c| (c.0, c.3))
}

fn nearest_ray(links: &[LinkGeom], t: f64, skip: Option<usize>) -> Option<usize> {
    let c = (0..links.len()).filter(move |&i| Some(i) != skip).map(move |i| {
        let off = (links[i].angle - t).rem_euclid(2.0 * PI);
        (ray_angle(links[i].angle, t), off > 0.0 && off <= PI, links[i].edge, i)
    });
    pick(c).map(|c| c.1)
}

impl Separation for ExampleSigma1Nearest {
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        failure.mode?;
        let (links, d) = (fan.links, fan.principal.theta1);
        if fan.closed {
            let first = nearest_ray(links, d, None)?;
            let second = nearest_ray(links, d + PI, Some(first))?;
            Some(Proposal { edges: vec![links[first].edge, links[second].edge] })
        } else {
            let c = (0..links.len()).map(|i| {
                let off = (links[i].angle - d).rem_euclid(PI);
                (line_angle(links[i].angle, d), off > 0.0 && off <= FRAC_PI_2, links[i].edge, i)
            });
            let (dist, i) = pick(c)?;
            // The paper's pi/4 cap is for points that have split already (METHOD 5): a point
            // never split (a boundary point) is cut whatever the angle, as the built-in does.
            (fan.never_split || dist < std::f64::consts::FRAC_PI_4).then(|| Proposal { edges: vec![links[i].edge] })
        }
    }
}

/// Panics on purpose, in `create` (`when = "create"`) or at the first `check` (`when = "check"`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExamplePanic {
    pub when: String,
}

impl Criterion for ExamplePanic {
    fn validate(&self) -> Result<(), ParamError> {
        match self.when.as_str() {
            "create" => panic!("example_panic: asked to panic in create"),
            "check" => Ok(()),
            w => Err(ParamError::new("when", format!("= \"{w}\" is incorrect; it must be \"create\" or \"check\""))),
        }
    }

    fn check(&self, p: &Principal, _scale: f64) -> FailureCheck {
        panic!("example_panic: asked to panic in check (s1 = {})", p.s1)
    }
}

flem_plugin_sdk::export_plugins!(
    criterion "example_rankine" => ExampleRankine,
    separation "example_sigma1_nearest" => ExampleSigma1Nearest,
    criterion "example_panic" => ExamplePanic,
    contact "example_spring_dashpot" => contact::ExampleSpringDashpot,
    damping "example_adaptive" => damping::ExampleAdaptive,
    material "example_mohr_coulomb" => material::ExampleMohrCoulomb,
    material "example_nan_law" => material::ExampleNanLaw,
);
