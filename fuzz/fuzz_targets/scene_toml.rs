//! The scene reader on arbitrary text (files it names are looked up in a folder that does
//! not exist, so only the parsing and checking run).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::scene::Scene;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Scene::from_toml(text, Path::new("/nonexistent-fuzz"), Path::new("fuzz.toml"));
    }
});
