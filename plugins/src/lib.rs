//! FLEM's built-in plugins. Each is one file with one registration line (`#[typetag::serde]`),
//! selected in a scene by `type = "name"`.
pub mod check;
pub mod contact;
pub mod criteria;
pub mod damping;
pub mod elements;
pub mod elements3d;
pub mod import;
pub mod material;
pub mod separation;
#[doc(hidden)]
pub mod snippets;

/// Every built-in plugin as (kind, name), in a fixed order (`flem plugins`).
pub fn registry() -> Vec<(&'static str, &'static str)> {
    let mut v = Vec::new();
    v.extend(damping::NAMES.iter().map(|n| ("damping", *n)));
    v.extend(criteria::NAMES.iter().map(|n| ("criterion", *n)));
    v.extend(separation::NAMES.iter().map(|n| ("separation", *n)));
    v.extend(contact::NAMES.iter().map(|n| ("contact", *n)));
    v.extend(material::NAMES.iter().map(|n| ("material", *n)));
    v.push(("check", "faer_cholesky"));
    v.extend(flem_core::element::registry::kinds().iter().map(|k| ("element", k.name)));
    v.extend(["rectangle", "rectangles", "gmsh", "vtk"].iter().map(|n| ("mesh", *n)));
    v
}

/// Call once from a binary so that the linker keeps this crate (typetag registrations).
pub fn link() {}
