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
use crate::element::kernel::LANES;
use crate::element::{Dmat, Material, Plane};
use crate::ids::ElemId;
use crate::mesh::CellKind;

/// A stress-update law (contract of issues 20/21, item 3).
pub trait MaterialLaw: Clone + Send + Sync + 'static {
    /// f64 of history per integration point, kept in core-owned arrays.
    const STATE: usize;
    /// The same, as the block reads it: `STATE` for a compiled law (a constant after
    /// inlining); a law loaded at run time declares its own.
    #[inline(always)]
    fn n_state(&self) -> usize {
        Self::STATE
    }
    /// An error the law met in an update (a dynamic law that failed or returned a non-finite
    /// stress; it then wrote NaN, which the divergence guard stops on): the solver reports it.
    fn fault(&self) -> Option<String> {
        None
    }
    /// Elastic moduli (stable step, implicit check, initial tangent).
    fn elastic(&self) -> Dmat;
    /// Stress update: `stress` = [sxx, syy, sxy, szz] at the start of the step, `deps` =
    /// [dexx, deyy, dgxy, dezz] the strain increment; updates both in place.
    fn update(&self, stress: &mut [f64; 4], deps: [f64; 4], state: &mut [f64]);
    /// `update` of lanes `0..n` of a pack of points (structure of arrays: `s[c][l]` is stress
    /// component `c` of lane `l`, `de[c][l]` its strain increment; lane `l`'s history is
    /// `state[l * stride..l * stride + n_state()]`). Must give bit for bit what `update` gives
    /// on each lane (the stateful block calls this in its vectorised path, directly or through
    /// [`Self::update_points_lanes`], and `update` in the others). The default calls `update`
    /// lane by lane; a law overrides it with a vectorised elastic trial and calls `update` only
    /// for the lanes that yield (`mohr_coulomb`).
    #[inline(always)]
    fn update_lanes(&self, s: &mut [[f64; LANES]; 4], de: &[[f64; LANES]; 4], state: &mut [f64], stride: usize, n: usize) {
        let ns = self.n_state();
        for l in 0..n.min(LANES) {
            let mut sl = [s[0][l], s[1][l], s[2][l], s[3][l]];
            self.update(&mut sl, [de[0][l], de[1][l], de[2][l], de[3][l]], &mut state[l * stride..l * stride + ns]);
            for c in 0..4 {
                s[c][l] = sl[c];
            }
        }
    }
    /// [`Self::update_lanes`] of every point of a pack at once: point `k` of the `s.len()`
    /// (`s[k]`, `de[k]`; its lanes' history at `state[k * ns + l * stride..]`, `ns` =
    /// `n_state()`; the caller keeps `stride >= s.len() * ns`, so that the points' histories do
    /// not overlap). The same bits as calling `update_lanes` point by point, which the default
    /// does; an override must keep them, point `k` touching only `s[k]` and its own history
    /// (`mohr_coulomb` handles the points that yield together: one out-of-line call per pack
    /// instead of one per point; ours, session 37).
    #[inline(always)]
    fn update_points_lanes(&self, s: &mut [[[f64; LANES]; 4]], de: &[[[f64; LANES]; 4]], state: &mut [f64], stride: usize, n: usize) {
        let ns = self.n_state();
        debug_assert_eq!(s.len(), de.len());
        for (k, (sk, dk)) in s.iter_mut().zip(de).enumerate() {
            self.update_lanes(sk, dk, &mut state[k * ns..], stride, n);
        }
    }
    /// True for a law that, from its initial state (zero stress, zero history), stays linear
    /// elastic and leaves its history untouched until it first yields. The stateful block then
    /// gives a point that has never yielded the stress of its total strain
    /// ([`Self::initial_lanes`]) without storing or reading anything of it
    /// (`StatefulOpts::elastic_shortcut`, docs/materials.md). Default false: every point is
    /// stored and updated incrementally (a law loaded at run time).
    fn elastic_start(&self) -> bool {
        false
    }
    /// For a law with [`Self::elastic_start`]: `s` = the stress that `update` gives from the
    /// initial state with the increment `e` (`[exx, eyy, gxy, ezz]`, the total strain of a point
    /// that never yielded), and for each lane whether that update is elastic (true only when
    /// it surely is: a lane answered false goes, with its pack, to the stored path, which is
    /// seeded with the last step's stress of the shortcut and goes on with the increment since
    /// then; from the initial state on a pack's first step). The default answers false
    /// for every lane.
    #[inline(always)]
    fn initial_lanes(&self, _e: &[[f64; LANES]; 4], s: &mut [[f64; LANES]; 4]) -> [bool; LANES] {
        *s = [[0.0; LANES]; 4];
        [false; LANES]
    }
    /// The consistent (algorithmic) tangent of [`Self::update`]: `out[i][j]` = the derivative
    /// of component `i` of the stress that `update(stress, deps, state)` gives with respect to
    /// `deps[j]` (the same component orders), at the given start of the update, which the
    /// call does not change. For a return map this is the tangent of the discrete map (de Souza
    /// Neto, Peric & Owen 2008, section 4.3.4), not the continuum elasto-plastic one: Newton
    /// iterations on it converge quadratically (the implicit plastic check,
    /// `flem-plugins/src/check/newton.rs`). `false` (the default): the law has none, and a
    /// caller falls back to the elastic moduli, saying so.
    fn tangent(&self, _stress: &[f64; 4], _deps: [f64; 4], _state: &[f64], _out: &mut [[f64; 4]; 4]) -> bool {
        false
    }
    /// True when [`Self::tangent`] is symmetric for every argument (associated flow): a
    /// caller may then factorise by Cholesky. Default false.
    fn tangent_symmetric(&self) -> bool {
        false
    }
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
    /// The moduli themselves (the law is linear), as `update` applies them: the in-plane
    /// stress does not see `dezz`; the out-of-plane row of plane strain, zero in plane stress.
    fn tangent(&self, _stress: &[f64; 4], _deps: [f64; 4], _state: &[f64], out: &mut [[f64; 4]; 4]) -> bool {
        let d = &self.d;
        *out = [[d.d11, d.d12, 0.0, 0.0], [d.d12, d.d11, 0.0, 0.0], [0.0, 0.0, d.d33, 0.0], [0.0; 4]];
        if self.plane == Plane::Strain {
            let (l, l2g) = (self.lambda, self.lambda + 2.0 * self.g);
            out[3] = [l, l, 0.0, l2g];
        }
        true
    }
    fn tangent_symmetric(&self) -> bool {
        true
    }
    /// `update` on every lane at once (no history, no branch per lane).
    #[inline(always)]
    fn update_lanes(&self, s: &mut [[f64; LANES]; 4], de: &[[f64; LANES]; 4], _state: &mut [f64], _stride: usize, _n: usize) {
        let d = &self.d;
        let strain = self.plane == Plane::Strain;
        let (l, l2g) = (self.lambda, self.lambda + 2.0 * self.g);
        for k in 0..LANES {
            s[0][k] += d.d11 * de[0][k] + d.d12 * de[1][k];
            s[1][k] += d.d12 * de[0][k] + d.d11 * de[1][k];
            s[2][k] += d.d33 * de[2][k];
            if strain {
                s[3][k] += l * (de[0][k] + de[1][k]) + l2g * de[3][k];
            }
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
    /// Points that never yielded take the stress of their total strain and store nothing
    /// (ours; small strain, laws with `MaterialLaw::elastic_start`; `[[material]]
    /// elastic_shortcut`, default true; see `stateful.rs`).
    pub elastic_shortcut: bool,
}

/// The elements of one region, by cell type, that a law's blocks are built from, and the
/// element kind (registered name, `element::registry`) the region's material chose for each
/// cell type.
#[derive(Clone, Debug, Default)]
pub struct RegionElems {
    /// Quadrilateral cells (`CellKind::Q4`).
    pub q4: Vec<(ElemId, [[f64; 2]; 4], [u32; 4])>,
    /// Triangle cells (`CellKind::T3`).
    pub t3: Vec<(ElemId, [[f64; 2]; 3], [u32; 3])>,
    /// Element kind of the quadrilaterals.
    pub q4_kind: &'static str,
    /// Element kind of the triangles.
    pub t3_kind: &'static str,
}

impl RegionElems {
    /// Calls `f(id, corners, clusters)` for every cell of type `cell`.
    pub fn for_cell(&self, cell: CellKind, mut f: impl FnMut(ElemId, &[[f64; 2]], &[u32])) {
        match cell {
            CellKind::Q4 => self.q4.iter().for_each(|(e, x, c)| f(*e, x, c)),
            CellKind::T3 => self.t3.iter().for_each(|(e, x, c)| f(*e, x, c)),
        }
    }
    /// The element kind chosen for cell type `cell`.
    pub fn kind_of(&self, cell: CellKind) -> &'static str {
        match cell {
            CellKind::Q4 => self.q4_kind,
            CellKind::T3 => self.t3_kind,
        }
    }
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.q4.len() + self.t3.len()
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
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

/// Builds a `[[material]] law` table naming a law from a loaded plugin library (`None`: no
/// loaded law has its `type`). Set once by the plugin loader (`plugin::dynload`, a layer above
/// this one), so that the scene's law tables reach the libraries without this layer knowing them.
pub static DYN_LAW: std::sync::OnceLock<fn(&toml::Value) -> Option<Box<dyn LawCfg>>> = std::sync::OnceLock::new();

/// `deserialize_with` for `[[material]] law`: a loaded plugin's law (see [`DYN_LAW`]), else a
/// built-in (typetag).
pub fn de_law<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Box<dyn LawCfg>>, D::Error> {
    use serde::Deserialize;
    let v = toml::Value::deserialize(d)?;
    if let Some(law) = DYN_LAW.get().and_then(|f| f(&v)) {
        return Ok(Some(law));
    }
    Box::<dyn LawCfg>::deserialize(v).map(Some).map_err(serde::de::Error::custom)
}

impl Clone for Box<dyn LawCfg> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}
