//! Test fixture: a shared library without `flem_plugin_entry_v1` (the loader must report the
//! missing symbol with the system loader's message).

/// Some exported function, not the FLEM entry point.
#[unsafe(no_mangle)]
pub extern "C" fn not_a_flem_plugin() -> i32 {
    42
}
