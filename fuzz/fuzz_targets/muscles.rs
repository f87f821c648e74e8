//! Muscle tables (`wearer.muscles_file`): parse, validate and evaluate arbitrary text.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::scenario::fuzz_muscles(text);
    }
});
