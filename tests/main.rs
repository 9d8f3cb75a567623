//! The one integration-test binary (cargo/ripgrep style: `autotests = false`, links once).
//! Every verification test names its reference and tolerance.
mod cavity;
mod ckpt;
mod common;
mod compare;
mod configs;
mod contact;
mod cracking;
mod dynkinds;
mod dynplug;
mod elements;
mod events;
mod fuzz;
mod implicit_plastic;
mod interop;
mod layout;
mod nonlocal;
mod paper;
mod parallel;
mod plasticity;
mod skip;
mod slope;
mod softening;
mod verification;
mod zero_free;
