//! A fault campaign's matrix (`exoleg faults --matrix FILE`): arbitrary text through the real
//! reader (TOML, the matrix's shape and bounds).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::study::faults::parse_matrix("fuzz", text);
    }
});
