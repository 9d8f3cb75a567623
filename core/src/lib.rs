//! FLEM core: the flow element method with node separation.
//!
//! See ARCHITECTURE.md at the repository root for the map. In short: a [`mesh::RawMesh`] becomes
//! a [`model::Model`] (topology of copies and clusters + element blocks); a
//! [`scene::Scene`] (validated TOML) drives a [`solver::Simulation`] through stages; results go
//! out through [`output`].
pub mod block;
pub mod check;
pub mod checkpoint;
pub mod contact;
pub mod corot;
pub mod damping;
pub mod dynload;
pub mod element;
pub mod error;
pub mod ids;
pub mod kernel;
pub mod mesh;
pub mod topology;
pub mod traits;
pub mod weibull;

pub use error::{FlemError, Result};

/// The FLEM core version (checked by the dynamic plugin loader).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
pub mod cracking;
pub mod loads;
pub mod model;
pub mod output;
pub mod scene;
pub mod solver;
