//! The one integration-test binary (cargo/ripgrep style: `autotests = false`, links once).
//! Every verification test names its reference and tolerance.
mod common;
mod configs;
mod cracking;
mod interop;
mod verification;
mod contact;
