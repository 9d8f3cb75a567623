//! What plugins implement and how they are found: the failure-criterion and separation-rule
//! traits ([`traits`]), the implicit check solver trait and the `[check]` section ([`check`]),
//! the damping scheme trait and its per-node coefficients ([`damping`]), and the loader of plugin
//! shared libraries ([`dynload`]). Contact laws (`crate::contact`) and mesh sources (`crate::mesh`)
//! keep their traits beside the data they act on.
pub mod check;
pub mod damping;
pub mod dynload;
pub mod support;
pub mod traits;
