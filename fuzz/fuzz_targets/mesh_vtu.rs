//! The Vtu reader on arbitrary bytes: a mesh or an error, never a panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::io::{self, Format};

fuzz_target!(|data: &[u8]| {
    let _ = io::parse(Format::Vtu, data, Path::new("fuzz.vtu"));
});
