//! The TetGen readers on arbitrary bytes: the input is split into a `.node`, an `.ele` and a
//! `.face` part at the first two 0xFF bytes, read in the order `io::read` reads a set.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use tissue::io::tetgen;

fuzz_target!(|data: &[u8]| {
    let mut parts = data.splitn(3, |&b| b == 0xFF);
    let node = parts.next().unwrap_or_default();
    let ele = parts.next().unwrap_or_default();
    let face = parts.next().unwrap_or_default();
    if let Ok((mut mesh, base)) = tetgen::parse_node(node, Path::new("fuzz.node")) {
        let _ = tetgen::parse_ele(ele, Path::new("fuzz.ele"), base, &mut mesh);
        let _ = tetgen::parse_face(face, Path::new("fuzz.face"), base, &mut mesh);
    }
});
