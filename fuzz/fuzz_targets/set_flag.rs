//! `--set KEY=VALUE` flags: arbitrary overrides (one per line) on the embedded default scenario.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::scenario::fuzz_set_flags(text);
    }
});
