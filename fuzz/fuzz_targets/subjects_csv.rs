//! A gait folder's `subjects.csv` (`exoleg gait-check`): the table and every row from arbitrary
//! text.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = exoleg::scenario::fuzz_subjects_csv(text);
    }
});
