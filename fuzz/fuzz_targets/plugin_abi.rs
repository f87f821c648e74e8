//! What the host makes of a plugin's bytes: its message buffer (one line, control characters
//! escaped) and channel names (accepted names make a sound CSV header).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = exoleg::control::plugin::fuzz_plugin_abi(data) {
        assert!(!e.starts_with("a control character") && !e.starts_with("accepted names"), "{e}");
    }
});
