//! A shard's `shard.json` (read by `exoleg merge`): parse and check arbitrary text.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::study::shard::fuzz_shard_json(text);
    }
});
