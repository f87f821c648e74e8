//! The wire protocol of a controller outside the process (an isolated plugin's socket pair, a
//! HIL peer's UDP datagrams): any bytes decode to a message or an error, never a panic, and a
//! decoded fixed-layout message encodes back to its bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = exoleg::control::wire::fuzz_wire(data) {
        assert!(!e.starts_with("a decoded message") && !e.starts_with("re-encoded"), "{e}");
    }
});
