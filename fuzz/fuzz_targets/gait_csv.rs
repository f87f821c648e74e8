//! Gait CSV text: parse and fit a gait cycle from arbitrary text.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::scenario::fuzz_gait_csv(text);
    }
});
