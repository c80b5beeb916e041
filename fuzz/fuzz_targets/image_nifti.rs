//! The NIfTI-1 reader (plain or gzip) on arbitrary bytes.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::image::nifti;

fuzz_target!(|data: &[u8]| {
    let _ = nifti::parse(data, Path::new("fuzz.nii"));
});
