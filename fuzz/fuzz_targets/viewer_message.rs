//! The viewer's WebSocket message parser (the binary crate's `view/messages.rs`, included by
//! path) on arbitrary text.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[allow(dead_code)]
#[path = "../../crates/tissue-cli/src/view/messages.rs"]
mod messages;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let bounds = messages::Bounds {
            center: tissue::Vec3::new(0.0, 0.05, 0.0),
            radius: 0.1,
        };
        let _ = messages::parse(text, &bounds);
    }
});
