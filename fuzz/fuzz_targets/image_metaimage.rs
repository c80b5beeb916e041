//! The MetaImage reader on arbitrary bytes; a detached data file is the input's tail after
//! its first 0xFF byte, so the fuzzer reaches the data path too.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::image::metaimage;

fuzz_target!(|data: &[u8]| {
    let (head, tail) = match data.iter().position(|&b| b == 0xFF) {
        Some(k) => (&data[..k], data[k + 1..].to_vec()),
        None => (data, Vec::new()),
    };
    let _ = metaimage::parse_with(head, Path::new("fuzz.mhd"), 0.001, &|_| Ok(tail.clone()));
});
