//! Test fixture for tests/dynkinds.rs: a library of the current ABI and core version whose
//! contact law `broken_contact` lacks its `contact_evaluate` function (as a library written by
//! hand against an older header might). The host must refuse the library when it loads,
//! naming the library, the plugin and the missing function, before anything runs.
use flem_plugin_sdk::abi::{Descriptor, PluginEntry};
use flem_plugin_sdk::{Contact, PairForce, PairKinematics};

#[derive(serde::Deserialize)]
pub struct Broken {}

impl Contact for Broken {
    const STATE: usize = 0;
    fn stiffness(&self) -> f64 {
        1.0
    }
    fn evaluate(&self, _k: &PairKinematics, _fresh: bool, _state: &mut [f64]) -> PairForce {
        PairForce::default()
    }
}

static PLUGINS: [PluginEntry; 1] = [PluginEntry { contact_evaluate: None, ..flem_plugin_sdk::contact_entry::<Broken>("broken_contact") }];
static DESCRIPTOR: Descriptor = flem_plugin_sdk::descriptor(&PLUGINS);

/// The entry point, with the incomplete table.
#[unsafe(no_mangle)]
pub extern "C" fn flem_plugin_entry_v1() -> *const Descriptor {
    &DESCRIPTOR
}
