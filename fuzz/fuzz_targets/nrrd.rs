//! NRRD, attached or detached data. Body: [`tomograf_fuzz::targets`].
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    tomograf_fuzz::targets::nrrd(data);
});
