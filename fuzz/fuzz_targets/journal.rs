//! A study's journal (`--resume`): arbitrary `runs.jsonl` bytes through the real reader.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = exoleg::study::journal::fuzz_journal(data);
});
