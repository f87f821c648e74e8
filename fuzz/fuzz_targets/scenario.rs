//! Scenario files: parse, validate and resolve arbitrary text (the embedded URDFs and trials;
//! a path inside is looked up like any other). Must return Ok or an error, never panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::scenario::fuzz_scenario(text);
    }
});
