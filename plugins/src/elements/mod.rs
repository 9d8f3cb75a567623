//! Element kinds beyond core's `q4` and `t3` (the element trait: `flem_core::element::kernel::
//! Blocked`; the registry: `flem_core::element::registry`; docs/elements.md). Each file is one
//! element and one `inventory::submit!` registration line, chosen by
//! `[[material]] element = "name"`.
pub mod qm6;

pub use qm6::Qm6;

#[cfg(test)]
mod tests;
