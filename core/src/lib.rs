//! FLEM core: the flow element method with node separation.
//!
//! See ARCHITECTURE.md at the repository root for the map. In short: a [`mesh::RawMesh`] becomes
//! an [`element::model::Model`] (topology of copies and clusters + element blocks); a
//! [`scene::Scene`] (validated TOML) drives a [`solver::Simulation`] through stages; results go
//! out through [`output`].
pub mod contact;
pub mod cracking;
pub mod element;
pub mod error;
pub mod expr;
pub mod ids;
pub mod mesh;
pub mod output;
pub mod plugin;
pub mod scene;
pub mod scene3;
pub mod solver;

pub use error::{FlemError, Result};

/// The FLEM core version (checked by the dynamic plugin loader).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
