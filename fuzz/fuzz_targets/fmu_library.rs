//! `exoleg fmu`'s checks of a library (`--library`: exoleg's FMU library of this version) and
//! of an existing `--out` file (an FMU exoleg wrote), on arbitrary bytes, never loaded.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = exoleg::fmu::fuzz_fmu_library(data);
});
