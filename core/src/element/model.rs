//! The model: mesh groups, the topology of copies and clusters, and the element blocks.
use serde::{Deserialize, Serialize};

use crate::element::block::Block;
use crate::element::law::{LawCfg, LinearElastic, RegionElems, StatefulOpts};
use crate::element::registry;
use crate::element::{Material, Plane};
use crate::error::{FlemError, Result};
use crate::ids::{EdgeId, ElemId, PointId};
use crate::mesh::topology::{SplitRecord, Topology};
use crate::mesh::{CellKind, RawMesh};

/// `[[material]]`: the material of an element region (linear elastic; METHOD section 2).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialCfg {
    /// Element region (mesh group) this material applies to; "all" for every element.
    #[serde(default = "all")]
    pub region: String,
    pub young_modulus: f64,
    pub poisson_ratio: f64,
    pub density: f64,
    #[serde(default = "one")]
    pub thickness: f64,
    /// Co-rotational kinematics (crate::element::corot): rigid rotations carry no stress.
    #[serde(default)]
    pub corotational: bool,
    /// Element kind of this region's cells of that kind's cell type (`element::registry`,
    /// docs/elements.md): "q4", "t3", "qm6" (ours: incompatible modes, no bending locking), "q4_closed" (ours: q4
    /// with its Gauss sum in closed form on parallelograms).
    /// Default by cell type: quadrilaterals "q4", triangles "t3" (the paper's elements).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub element: Option<String>,
    /// Material law (`crate::element::law`; built-ins in `flem-plugins/src/material/`).
    /// Absent: linear elastic on the stateless blocked kernel. A loaded plugin's law too
    /// (`law::de_law`).
    #[serde(default, skip_serializing_if = "Option::is_none", deserialize_with = "crate::element::law::de_law")]
    pub law: Option<Box<dyn LawCfg>>,
    /// Mean-dilatation B-bar on Q4 for stateful blocks (`element::stateful`; default true).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bbar: Option<bool>,
    /// Stateful blocks: a point that never yielded takes the stress of its total strain and
    /// stores nothing (ours, `element::stateful`; default true; false keeps every point's
    /// stress stored and updated incrementally, the plain path).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elastic_shortcut: Option<bool>,
}

impl MaterialCfg {
    /// A linear elastic material for every region (`region = "all"`), unit thickness, no
    /// co-rotation, the default element kind of each cell type and the default law: what a
    /// generated model (benches, tests) needs; one place to grow when `[[material]]` does.
    pub fn elastic(young_modulus: f64, poisson_ratio: f64, density: f64) -> Self {
        MaterialCfg { region: all(), young_modulus, poisson_ratio, density, thickness: 1.0, corotational: false, element: None, law: None, bbar: None, elastic_shortcut: None }
    }
}

fn all() -> String {
    "all".into()
}
fn one() -> f64 {
    1.0
}

pub struct Model {
    pub mesh: RawMesh,
    pub topo: Topology,
    pub blocks: Vec<Box<dyn Block>>,
    /// (block, local index) of every element.
    pub elem_slot: Vec<(u32, u32)>,
    pub plane: Plane,
    /// Worker threads of the element loop and the node update (`solver.threads`); `None`: one
    /// thread, no pool. Results do not depend on it (see `kernel`).
    pub pool: Option<std::sync::Arc<rayon::ThreadPool>>,
    /// Some block is co-rotational (its forces are not linear in u).
    pub corotational: bool,
    /// Some block is stateful (a law with history, or large strain: `element::stateful`).
    pub stateful: bool,
}

/// Model-wide options from the scene.
#[derive(Clone, Copy, Debug, Default)]
pub struct ModelOpts {
    /// `[solver] large_strain`: every block is stateful, updated Lagrangian.
    pub large_strain: bool,
}

impl Model {
    /// Builds blocks (one per region and element kind) from a validated mesh.
    pub fn new(mesh: RawMesh, materials: &[MaterialCfg], plane: Plane, scene_file: &str) -> Result<Model> {
        Self::new_with(mesh, materials, plane, ModelOpts::default(), scene_file)
    }

    /// [`Self::new`] with model-wide options (large strain).
    pub fn new_with(mesh: RawMesh, materials: &[MaterialCfg], plane: Plane, opts: ModelOpts, scene_file: &str) -> Result<Model> {
        let topo = Topology::new(&mesh);
        let mut regions: Vec<&str> = mesh.cell_region.iter().map(String::as_str).collect();
        regions.sort_unstable();
        regions.dedup();
        for (i, m) in materials.iter().enumerate() {
            if m.region != "all" && !regions.contains(&m.region.as_str()) {
                return Err(FlemError::config(scene_file, format!("material[{i}].region"), format!("= \"{}\" names no element region of the mesh; regions are {regions:?}", m.region)));
            }
        }
        let mat_of = |region: &str| -> Option<Material> {
            let m = materials.iter().find(|m| m.region == region).or_else(|| materials.iter().find(|m| m.region == "all"))?;
            Some(Material { young: m.young_modulus, poisson: m.poisson_ratio, density: m.density, thickness: m.thickness, plane })
        };
        let cfg_of = |region: &str| materials.iter().enumerate().find(|(_, m)| m.region == region).or_else(|| materials.iter().enumerate().find(|(_, m)| m.region == "all"));
        let corot_of = |region: &str| cfg_of(region).is_some_and(|(_, m)| m.corotational);
        // The element kind of each material that names one (checked before anything is built).
        for (i, m) in materials.iter().enumerate() {
            if let Some(name) = &m.element {
                if registry::find(name).is_none() {
                    let names: Vec<&str> = registry::kinds().iter().map(|k| k.name).collect();
                    let hint = crate::error::nearest(name, names.iter().copied()).map(|h| format!(" (did you mean \"{h}\"?)")).unwrap_or_default();
                    return Err(FlemError::config(scene_file, format!("material[{i}].element"), format!("= \"{name}\" is no element kind{hint}; element kinds are {names:?}")));
                }
            }
            if let Some(law) = &m.law {
                let mat = Material { young: m.young_modulus, poisson: m.poisson_ratio, density: m.density, thickness: m.thickness, plane };
                law.validate(&mat).map_err(|(k, msg)| FlemError::config(scene_file, format!("material[{i}].law.{k}"), msg))?;
                if m.corotational && !law.is_linear_elastic() {
                    return Err(FlemError::config(
                        scene_file,
                        format!("material[{i}].corotational"),
                        "= true works with the linear elastic law only; for large rotations of another law use [solver] large_strain = true",
                    ));
                }
            }
        }
        let kind_of = |region: &str, cell: CellKind| -> Result<&'static registry::ElementKind> {
            let named = cfg_of(region).and_then(|(_, m)| m.element.as_deref()).and_then(registry::find).filter(|k| k.cell == cell);
            named.or_else(|| registry::default_for(cell)).ok_or_else(|| {
                FlemError::config(
                    scene_file,
                    "material",
                    format!(
                        "no element kind \"{}\" is linked for the {cell:?} cells of region \"{region}\" (the built-in kinds are in flem-plugins: call flem_plugins::link())",
                        crate::element::default_kind(cell)
                    ),
                )
            })
        };
        let mut stateful = false;
        let mut blocks: Vec<Box<dyn Block>> = Vec::new();
        let mut elem_slot = vec![(0u32, 0u32); mesh.cells.len()];
        for region in &regions {
            let mat = mat_of(region)
                .ok_or_else(|| FlemError::config(scene_file, "material", format!("gives no material for element region \"{region}\" (add [[material]] region = \"{region}\" or region = \"all\")")))?;
            let corot = corot_of(region);
            let (mi, mcfg) = cfg_of(region).expect("mat_of found it");
            let law_linear = mcfg.law.as_ref().is_none_or(|l| l.is_linear_elastic());
            if !law_linear || opts.large_strain {
                // A material law with state, or large strain: the stateful block
                // (`element::stateful`, Q4 with B-bar and T3; issue 21).
                if corot {
                    return Err(FlemError::config(
                        scene_file,
                        format!("material[{mi}].corotational"),
                        "= true cannot be combined with [solver] large_strain = true (large strain already rotates the stress with the body)",
                    ));
                }
                let mut elems = RegionElems::default();
                for (e, c) in mesh.cells.iter().enumerate() {
                    if mesh.cell_region[e] != *region {
                        continue;
                    }
                    let x = |a: usize| mesh.points[c.nodes[a] as usize];
                    match c.kind {
                        CellKind::Q4 => elems.q4.push((ElemId::new(e), [x(0), x(1), x(2), x(3)], [c.nodes[0], c.nodes[1], c.nodes[2], c.nodes[3]])),
                        CellKind::T3 => elems.t3.push((ElemId::new(e), [x(0), x(1), x(2)], [c.nodes[0], c.nodes[1], c.nodes[2]])),
                    }
                }
                if !elems.q4.is_empty() {
                    elems.q4_kind = kind_of(region, CellKind::Q4)?.name;
                }
                if !elems.t3.is_empty() {
                    elems.t3_kind = kind_of(region, CellKind::T3)?.name;
                }
                let so = StatefulOpts { bbar: mcfg.bbar.unwrap_or(true), large_strain: opts.large_strain, elastic_shortcut: mcfg.elastic_shortcut.unwrap_or(true) };
                let built = match &mcfg.law {
                    Some(l) => l.build(region, mat, so, &elems),
                    None => build_stateful_elastic(region, mat, so, &elems),
                };
                // Every cell must be in a block: a kind without a stateful kernel for this law
                // builds none (named here, before anything runs).
                if built.iter().map(|b| b.len()).sum::<usize>() != elems.len() {
                    let name = mcfg.element.as_deref().unwrap_or("?");
                    return Err(FlemError::config(
                        scene_file,
                        format!("material[{mi}].element"),
                        format!("= \"{name}\" has no stateful kernel for this material law: a law other than linear elastic, or [solver] large_strain, runs on the kinds {:?}", stateful_kinds()),
                    ));
                }
                blocks.extend(built);
                stateful = true;
                continue;
            }
            // One block per cell type, quadrilaterals first (the order the model always had).
            for cell in [CellKind::Q4, CellKind::T3] {
                if !mesh.cells.iter().zip(&mesh.cell_region).any(|(c, r)| c.kind == cell && r == region) {
                    continue;
                }
                let mut b = kind_of(region, cell)?.builder(region.to_string(), mat);
                for (e, c) in mesh.cells.iter().enumerate() {
                    if mesh.cell_region[e] != *region || c.kind != cell {
                        continue;
                    }
                    let x: [[f64; 2]; 4] = std::array::from_fn(|a| c.corners().get(a).map_or([0.0; 2], |&p| mesh.points[p as usize]));
                    b.push(ElemId::new(e), &x[..c.corners().len()], c.corners());
                }
                if !b.is_empty() {
                    blocks.push(b.finish(corot));
                }
            }
        }
        for blk in blocks.iter_mut() {
            blk.prepare(topo.n_clusters());
        }
        if let [blk] = blocks.as_mut_slice() {
            // One block (the common case): its forces are the model's, so its pass may write
            // every entry instead of adding onto zeros (`Block::set_internal_forces_pool`).
            blk.enable_zero_free(topo.n_clusters());
        }
        for (b, blk) in blocks.iter().enumerate() {
            for (i, e) in blk.elems().iter().enumerate() {
                elem_slot[e.idx()] = (b as u32, i as u32);
            }
        }
        let corotational = materials.iter().any(|m| m.corotational);
        Ok(Model { mesh, topo, blocks, elem_slot, plane, pool: None, corotational, stateful })
    }

    /// Points of a named node set; the error names the set and the groups that exist.
    pub fn node_set(&self, name: &str, key: &str, file: &str) -> Result<Vec<PointId>> {
        match self.mesh.node_sets.get(name) {
            Some(v) => Ok(v.iter().map(|&p| PointId(p)).collect()),
            None => {
                let names: Vec<&str> = self.mesh.node_sets.keys().map(String::as_str).collect();
                let hint = crate::error::nearest(name, names.iter().copied()).map(|h| format!(" (did you mean \"{h}\"?)")).unwrap_or_default();
                Err(FlemError::config(file, key, format!("= \"{name}\" names no node set of the mesh{hint}; node sets are {names:?}")))
            }
        }
    }

    /// Edges of a named edge set.
    pub fn edge_set(&self, name: &str, key: &str, file: &str) -> Result<Vec<EdgeId>> {
        let set = self.mesh.edge_sets.get(name).ok_or_else(|| {
            let names: Vec<&str> = self.mesh.edge_sets.keys().map(String::as_str).collect();
            let hint = crate::error::nearest(name, names.iter().copied()).map(|h| format!(" (did you mean \"{h}\"?)")).unwrap_or_default();
            FlemError::config(file, key, format!("= \"{name}\" names no edge set of the mesh{hint}; edge sets are {names:?}"))
        })?;
        set.iter()
            .map(|&[p, q]| {
                self.topo
                    .edge_between(PointId(p), PointId(q))
                    .ok_or_else(|| FlemError::config(file, key, format!("= \"{name}\": {} are not joined by an element edge", self.mesh.points_name(&[p, q]))))
            })
            .collect()
    }

    /// Applies a split record to the blocks' connectivity.
    pub fn apply_record(&mut self, rec: &SplitRecord) {
        for nc in &rec.new_clusters {
            for &k in &nc.copies {
                let e = self.topo.copy_elem[k.idx()];
                let a = k.idx() - self.topo.elem_first_copy[e.idx()] as usize;
                let (b, i) = self.elem_slot[e.idx()];
                self.blocks[b as usize].remap(i as usize, a, nc.id.0);
            }
        }
        self.refresh_zero_free();
    }

    /// Moves point `p` to the reference coordinates `x` (ours: the crack-tip node relocation of
    /// the path method, `cracking::path`, issue 34) and rebuilds the blocks holding an element
    /// with a corner at `p` from the mesh's coordinates and their current clusters: geometry,
    /// gradients and lumped masses follow the new position; the connectivity and the element
    /// order are those of the block before. Refused (the reason as text, nothing changed) on a
    /// model with stateful or co-rotational blocks (their history or rotation would be lost) or
    /// a kind without a registered builder. The caller checks the elements' shapes first.
    pub fn move_point(&mut self, p: PointId, x: [f64; 2]) -> std::result::Result<(), String> {
        if self.stateful || self.corotational {
            return Err("the model has stateful or co-rotational blocks: a node cannot be moved".into());
        }
        let old = self.mesh.points[p.idx()];
        let mut touched: Vec<usize> = Vec::new();
        for &k in self.topo.point_copies.row(p.idx()) {
            let e = self.topo.copy_elem[k.idx()];
            let b = self.elem_slot[e.idx()].0 as usize;
            if !touched.contains(&b) {
                touched.push(b);
            }
        }
        touched.sort_unstable();
        for &b in &touched {
            if registry::find(self.blocks[b].element()).is_none() {
                return Err(format!("element kind \"{}\" has no registered builder", self.blocks[b].element()));
            }
        }
        self.mesh.points[p.idx()] = x;
        let n = self.topo.n_clusters();
        // Each element at the point in place (`Block::move_elem`: the tip's neighbourhood only,
        // bit for bit a rebuild); a block that cannot is rebuilt from the mesh.
        let mut rebuild: Vec<usize> = Vec::new();
        for &k in self.topo.point_copies.row(p.idx()) {
            let e = self.topo.copy_elem[k.idx()];
            let (b, i) = self.elem_slot[e.idx()];
            let xs: Vec<[f64; 2]> = self.mesh.cells[e.idx()].corners().iter().map(|&q| self.mesh.points[q as usize]).collect();
            if !rebuild.contains(&(b as usize)) && !self.blocks[b as usize].move_elem(i as usize, &xs) {
                rebuild.push(b as usize);
            }
        }
        rebuild.sort_unstable();
        for &b in &rebuild {
            let blk = &self.blocks[b];
            let kind = registry::find(blk.element()).expect("checked above");
            let mut nb = kind.builder(blk.region().to_string(), *blk.material());
            for (i, e) in blk.elems().iter().enumerate() {
                let c = &self.mesh.cells[e.idx()];
                let xs: Vec<[f64; 2]> = c.corners().iter().map(|&q| self.mesh.points[q as usize]).collect();
                nb.push(*e, &xs, blk.conn(i));
            }
            let mut nb = nb.finish(false);
            if nb.len() != self.blocks[b].len() {
                self.mesh.points[p.idx()] = old;
                return Err("a rebuilt block lost elements".into());
            }
            nb.prepare(n);
            self.blocks[b] = nb;
            for (i, e) in self.blocks[b].elems().iter().enumerate() {
                self.elem_slot[e.idx()] = (b as u32, i as u32);
            }
        }
        if let [blk] = self.blocks.as_mut_slice() {
            if !blk.zero_free() {
                blk.enable_zero_free(n);
            }
        }
        Ok(())
    }

    /// The zero-free pass's first writers after a split: the block rebuilds them from its
    /// re-pointed corners (one pass over the corners and the clusters, as at the start).
    fn refresh_zero_free(&mut self) {
        let n = self.topo.n_clusters();
        if let [b] = self.blocks.as_mut_slice() {
            if b.zero_free() {
                b.enable_zero_free(n);
            }
        }
    }

    /// Whether the model's force pass writes every entry instead of zeroing the array first
    /// (one block that plans it: `Block::set_internal_forces_pool`; `flem bench step`'s byte
    /// count).
    pub fn zero_free(&self) -> bool {
        matches!(self.blocks.as_slice(), [b] if b.zero_free())
    }

    /// Reference position of every cluster.
    pub fn cluster_x0(&self) -> Vec<[f64; 2]> {
        self.topo.cluster_point.iter().map(|p| self.mesh.points[p.idx()]).collect()
    }

    pub fn n_elems(&self) -> usize {
        self.topo.n_elems()
    }

    /// The forces of a one-block model by its zero-free pass (`Block::set_internal_forces_pool`);
    /// false, `f` untouched, when the model has no such pass.
    fn set_zero_free(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]) -> bool {
        matches!(self.blocks.as_slice(), [b] if b.set_internal_forces_pool(u, f, self.pool.as_deref()))
    }

    /// Internal forces of every block into `f` (zeroed first), on the model's pool if any. A
    /// model of one block whose pass writes every entry (`Block::set_internal_forces_pool`,
    /// the same bits) skips the zeroing sweep.
    pub fn internal_forces(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        if self.set_zero_free(u, f) {
            return;
        }
        f.iter_mut().for_each(|x| *x = [0.0; 2]);
        for b in &self.blocks {
            b.add_internal_forces_pool(u, f, self.pool.as_deref());
        }
    }

    /// Internal forces of the step into `f` (zeroed first): stateful blocks update their
    /// stress and history here (`Block::update_internal_forces`); call it once per step. One
    /// stateless block skips the zeroing sweep as in [`Self::internal_forces`].
    pub fn update_internal_forces(&mut self, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        if self.set_zero_free(u, f) {
            return;
        }
        let pool = self.pool.as_deref();
        f.iter_mut().for_each(|x| *x = [0.0; 2]);
        for b in self.blocks.iter_mut() {
            b.update_internal_forces(u, f, pool);
        }
    }

    /// Uses `threads` worker threads (0: one per available core; 1: no pool).
    pub fn set_threads(&mut self, threads: usize) -> std::result::Result<(), rayon::ThreadPoolBuildError> {
        let n = if threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { threads };
        self.pool = if n <= 1 { None } else { Some(std::sync::Arc::new(rayon::ThreadPoolBuilder::new().num_threads(n).build()?)) };
        Ok(())
    }

    /// Which dataflow the force passes run on several threads (issue 42, session 29; the same
    /// bits with either: `element::kernel::Dataflow`). `Auto` unless set.
    pub fn set_dataflow(&mut self, d: crate::element::kernel::Dataflow) {
        self.blocks.iter_mut().for_each(|b| b.set_dataflow(d));
    }

    /// Threads in use (1 without a pool).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// Strain energy of the elements with a corner at point `p`, `sum_e 1/2 u_e . K_e u_e` (ours,
    /// issue 36: what a node relocation of the path method changes, `Cracking::move_strain`).
    /// Linear blocks only (a model with stateful or co-rotational blocks never moves a node).
    pub fn strain_energy_at(&self, p: PointId, u: &[[f64; 2]]) -> f64 {
        let mut k = Vec::new();
        let mut e = 0.0;
        for &c in self.topo.point_copies.row(p.idx()) {
            let el = self.topo.copy_elem[c.idx()];
            let (b, i) = self.elem_slot[el.idx()];
            let blk = &self.blocks[b as usize];
            let n2 = 2 * blk.nodes_per_elem();
            k.clear();
            k.resize(n2 * n2, 0.0);
            blk.stiffness(i as usize, &mut k);
            let conn = blk.conn(i as usize);
            let ue = |r: usize| u[conn[r / 2] as usize][r % 2];
            for r in 0..n2 {
                let row: f64 = (0..n2).map(|s| k[r * n2 + s] * ue(s)).sum();
                e += 0.5 * ue(r) * row;
            }
        }
        e
    }

    /// Strain energy at `u`: each co-rotational block's own, plus `1/2 u . F_int` of the
    /// linear blocks (computed into `scratch`).
    pub fn strain_energy(&self, u: &[[f64; 2]], scratch: &mut Vec<[f64; 2]>) -> f64 {
        let mut e = 0.0;
        scratch.clear();
        scratch.resize(u.len(), [0.0; 2]);
        let mut any_linear = false;
        for b in &self.blocks {
            match b.strain_energy(u) {
                Some(x) => e += x,
                None => {
                    any_linear = true;
                    b.add_internal_forces(u, scratch);
                }
            }
        }
        if any_linear {
            e += 0.5 * u.iter().zip(scratch.iter()).map(|(u, f)| u[0] * f[0] + u[1] * f[1]).sum::<f64>();
        }
        e
    }

    /// Lumped mass of every cluster.
    /// Every block's saved state (`Block::save_state`: point stress, history, last displacements,
    /// internal work), in block order: what a checkpoint and `flem fos`'s warm start keep.
    pub fn block_states(&self) -> Vec<Vec<f64>> {
        self.blocks
            .iter()
            .map(|b| {
                let mut v = Vec::with_capacity(b.state_len());
                b.save_state(&mut v);
                v
            })
            .collect()
    }

    pub fn masses(&self) -> Vec<f64> {
        let mut m = vec![0.0; self.topo.n_clusters()];
        for b in &self.blocks {
            b.add_mass(&mut m);
        }
        m
    }

    /// Stress of every copy at its (0.9999-scaled) corner.
    pub fn corner_stresses(&self, u: &[[f64; 2]], out: &mut Vec<[f64; 3]>) {
        out.resize(self.topo.copy_point.len(), [0.0; 3]);
        for b in &self.blocks {
            b.corner_stress(u, &self.topo.elem_first_copy, out);
        }
    }

    /// `max_row sum_j |(A_k)_rj|` of the corner-stress operator of every copy (`Block::corner_lipschitz`),
    /// when every block can give it; false otherwise (`out` then undefined).
    pub fn corner_lipschitz(&self, out: &mut Vec<f64>) -> bool {
        out.clear();
        out.resize(self.topo.copy_point.len(), 0.0);
        self.blocks.iter().all(|b| b.corner_lipschitz(&self.topo.elem_first_copy, out))
    }

    /// Nodal stress of every cluster: the average over its copies (paper 2.1).
    pub fn nodal_stress(&self, u: &[[f64; 2]], corner: &mut Vec<[f64; 3]>, out: &mut Vec<[f64; 3]>) {
        self.nodal_stress_with(u, corner, out, &mut Vec::new());
    }

    /// [`Self::nodal_stress`] with a caller-kept scratch for the copy counts (no allocation
    /// once the buffers have grown: the failure check calls it every `check_every` steps).
    pub fn nodal_stress_with(&self, u: &[[f64; 2]], corner: &mut Vec<[f64; 3]>, out: &mut Vec<[f64; 3]>, cnt: &mut Vec<u32>) {
        self.corner_stresses(u, corner);
        let nc = self.topo.n_clusters();
        out.clear();
        out.resize(nc, [0.0; 3]);
        cnt.clear();
        cnt.resize(nc, 0);
        for (k, s) in corner.iter().enumerate() {
            let c = self.topo.copy_cluster[k].idx();
            for d in 0..3 {
                out[c][d] += s[d];
            }
            cnt[c] += 1;
        }
        for (s, &n) in out.iter_mut().zip(cnt.iter()) {
            if n > 0 {
                for v in s.iter_mut() {
                    *v /= n as f64;
                }
            }
        }
    }

    /// The material of element `e`.
    pub fn material_of(&self, e: ElemId) -> &Material {
        self.blocks[self.elem_slot[e.idx()].0 as usize].material()
    }
}
/// The stateful blocks of a region with the linear elastic law: each element kind's own
/// constructor (`registry::ElementKind::stateful_elastic`, monomorphised at registration).
pub fn build_stateful_elastic(region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>> {
    let mut out = Vec::new();
    for cell in [CellKind::Q4, CellKind::T3] {
        if let Some(ctor) = registry::find(elems.kind_of(cell)).and_then(|k| k.stateful_elastic) {
            out.extend(ctor(LinearElastic::new(&mat), region, mat, opts, elems));
        }
    }
    out
}

/// Names of the linked element kinds with a stateful kernel.
fn stateful_kinds() -> Vec<&'static str> {
    registry::kinds().iter().filter(|k| k.stateful_elastic.is_some()).map(|k| k.name).collect()
}

/// `law = { type = "linear_elastic" }`: the default, written out (the elastic constants are
/// those of the `[[material]]`).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearElasticCfg {}

#[typetag::serde(name = "linear_elastic")]
impl LawCfg for LinearElasticCfg {
    fn validate(&self, _mat: &Material) -> std::result::Result<(), (String, String)> {
        Ok(())
    }
    fn is_linear_elastic(&self) -> bool {
        true
    }
    fn build(&self, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>> {
        build_stateful_elastic(region, mat, opts, elems)
    }
    fn clone_box(&self) -> Box<dyn LawCfg> {
        Box::new(self.clone())
    }
}
