//! The NRRD reader on arbitrary bytes; a detached data file is the input's tail after its
//! first 0xFF byte.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::image::nrrd;

fuzz_target!(|data: &[u8]| {
    let (head, tail) = match data.iter().position(|&b| b == 0xFF) {
        Some(k) => (&data[..k], data[k + 1..].to_vec()),
        None => (data, Vec::new()),
    };
    let _ = nrrd::parse_with(head, Path::new("fuzz.nrrd"), &|_| Ok(tail.clone()));
});
