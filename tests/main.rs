//! The one integration-test binary (cargo/ripgrep style: `autotests = false`, links once).
//! Every verification test names its reference and tolerance.
mod common;
mod compare;
mod configs;
mod ckpt;
mod cracking;
mod dynplug;
mod interop;
mod paper;
mod parallel;
mod verification;
mod contact;
mod fuzz;
