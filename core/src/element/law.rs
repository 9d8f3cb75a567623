//! Material laws: the stress update of an integration point from a strain increment.
//!
//! Two traits:
//! - [`MaterialLaw`]: the law itself, monomorphised inside a stateful element block
//!   ([`crate::element::stateful::StatefulBlock`]); no dynamic dispatch per point.
//! - [`LawCfg`]: its `[[material]] law = { type = "...", ... }` configuration (typetag), which
//!   validates the parameters and builds the blocks of a region, once, when the model is built.
//!
//! Conventions: stress is tension-positive `[sxx, syy, sxy, szz]`, strain increments
//! `[dexx, deyy, dgxy, dezz]` with the engineering shear strain `dgxy = 2 dexy` (plane strain:
//! `dezz = 0`). A law's history is `STATE` f64 per integration point, kept in core-owned arrays
//! of the block (so checkpoints can carry them).
//!
//! The linear elastic law without `[solver] large_strain` never reaches this module: it keeps
//! the stateless blocked kernel (`element/kernel.rs`), so a scene without plasticity pays nothing.
//! [`LinearElastic`] is the same law in incremental form, for large strain (hypoelastic with an
//! objective rate) and as the reference the tests compare the stateful block with.
use std::fmt::Debug;

use crate::element::block::Block;
use crate::element::{Dmat, Material, Plane};
use crate::ids::ElemId;

/// A stress-update law (contract of issues 20/21, item 3).
pub trait MaterialLaw: Clone + Send + Sync + 'static {
    /// f64 of history per integration point, kept in core-owned arrays.
    const STATE: usize;
    /// Elastic moduli (stable step, implicit check, initial tangent).
    fn elastic(&self) -> Dmat;
    /// Stress update: `stress` = [sxx, syy, sxy, szz] at the start of the step, `deps` =
    /// [dexx, deyy, dgxy, dezz] the strain increment; updates both in place.
    fn update(&self, stress: &mut [f64; 4], deps: [f64; 4], state: &mut [f64]);
    /// What the output shows of a point's history: `(plastic shear strain, plastic state)`,
    /// the state 0 never plastic, 1 plastic in the last update, 2 plastic in the past only.
    fn output(&self, _state: &[f64]) -> (f64, u8) {
        (0.0, 0)
    }
}

/// Isotropic linear elasticity in incremental form: `dsigma = D deps` with the out-of-plane
/// component of plane strain, `dszz = lambda (dexx + deyy) + (lambda + 2 G) dezz`.
#[derive(Clone, Copy, Debug)]
pub struct LinearElastic {
    pub d: Dmat,
    /// Lame's lambda and G of the 3D law (plane strain) for the out-of-plane stress.
    pub lambda: f64,
    pub g: f64,
    pub plane: Plane,
}

impl LinearElastic {
    pub fn new(m: &Material) -> Self {
        let (e, nu) = (m.young, m.poisson);
        LinearElastic { d: m.dmat(), lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), g: e / (2.0 * (1.0 + nu)), plane: m.plane }
    }
}

impl MaterialLaw for LinearElastic {
    const STATE: usize = 0;
    fn elastic(&self) -> Dmat {
        self.d
    }
    #[inline(always)]
    fn update(&self, s: &mut [f64; 4], de: [f64; 4], _state: &mut [f64]) {
        let d = &self.d;
        s[0] += d.d11 * de[0] + d.d12 * de[1];
        s[1] += d.d12 * de[0] + d.d11 * de[1];
        s[2] += d.d33 * de[2];
        if self.plane == Plane::Strain {
            s[3] += self.lambda * (de[0] + de[1]) + (self.lambda + 2.0 * self.g) * de[3];
        }
    }
}

/// Options of a stateful block, from the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatefulOpts {
    /// Selective (mean-dilatation) volumetric strain for Q4: `B-bar` (see `stateful.rs`).
    pub bbar: bool,
    /// Updated Lagrangian kinematics with the Jaumann rate (Hughes-Winget increments).
    pub large_strain: bool,
}

/// The elements of one region, by kind, that a law's blocks are built from.
#[derive(Clone, Debug, Default)]
pub struct RegionElems {
    pub q4: Vec<(ElemId, [[f64; 2]; 4], [u32; 4])>,
    pub t3: Vec<(ElemId, [[f64; 2]; 3], [u32; 3])>,
}

/// `[[material]] law = { type = "...", ... }`: a material law's parameters (typetag; built-ins
/// in `flem-plugins/src/material/`).
#[typetag::serde(tag = "type")]
pub trait LawCfg: Debug + Send + Sync {
    /// Checks the parameters against the region's elastic material: `Err((key, message))`,
    /// the key relative to `law` (e.g. `"friction_angle"`).
    fn validate(&self, mat: &Material) -> Result<(), (String, String)>;
    /// True for the linear elastic law: without large strain the model keeps the stateless
    /// blocked kernel for it.
    fn is_linear_elastic(&self) -> bool {
        false
    }
    /// The law with its strength divided by `f` (strength reduction, `solver::fos`): `c / f`
    /// and `tan(phi) / f`, as the law defines them; `None` (the default) for a law without a
    /// strength to reduce, which `flem fos` leaves as it is.
    fn strength_reduced(&self, _f: f64) -> Option<Box<dyn LawCfg>> {
        None
    }
    /// The blocks (one per element kind present) of a region with this law.
    fn build(&self, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>>;
    fn clone_box(&self) -> Box<dyn LawCfg>;
}

impl Clone for Box<dyn LawCfg> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}
