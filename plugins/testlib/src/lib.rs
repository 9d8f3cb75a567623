//! Test fixture for tests/dynplug.rs: a library as an older FLEM would have built it. Its
//! descriptor header (the frozen first fields of `flem_core::plugin::dynload::abi::Descriptor`, written
//! out by hand since this crate has no dependencies) says plugin ABI 1 and FLEM core
//! "0.0.1-old"; the host must refuse it before reading anything else.

#[repr(C)]
pub struct RStr {
    ptr: *const u8,
    len: usize,
}

#[repr(C)]
pub struct Header {
    abi_version: u32,
    core_version: RStr,
    rustc_version: RStr,
    n_plugins: usize,
    plugins: *const u8,
}

// SAFETY: an immutable static.
unsafe impl Sync for Header {}

const CORE: &str = "0.0.1-old";
const RUSTC: &str = "rustc 1.0.0 (test fixture)";

static HEADER: Header = Header {
    abi_version: 1,
    core_version: RStr { ptr: CORE.as_ptr(), len: CORE.len() },
    rustc_version: RStr { ptr: RUSTC.as_ptr(), len: RUSTC.len() },
    // Never read by a correct host: a wrong count and a null table.
    n_plugins: 1000,
    plugins: std::ptr::null(),
};

/// The entry point, returning the stale header.
#[unsafe(no_mangle)]
pub extern "C" fn flem_plugin_entry_v1() -> *const Header {
    &HEADER
}
