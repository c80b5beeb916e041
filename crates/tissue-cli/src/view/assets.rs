//! The viewer's page, built into the binary: `tissue view` serves it from any folder after
//! `cargo install`, with no checkout and no npm. three.js is vendored in
//! `viewer/vendor/three/` (MIT, its LICENSE beside it). `--viewer-dir` serves a folder
//! instead (editing the page without rebuilding).

/// One embedded file: its URL path (without the leading `/`) and bytes.
pub struct Asset {
    pub path: &'static str,
    pub bytes: &'static [u8],
}

macro_rules! asset {
    ($path:literal) => {
        Asset {
            path: $path,
            bytes: include_bytes!(concat!("../../../../viewer/", $path)),
        }
    };
}

/// Every file the page loads.
pub const ASSETS: &[Asset] = &[
    asset!("index.html"),
    asset!("style.css"),
    asset!("src/main.js"),
    asset!("src/orbit.js"),
    asset!("src/organ.js"),
    asset!("src/plot.js"),
    asset!("src/colormap.js"),
    asset!("vendor/three/three.module.js"),
    asset!("vendor/three/three.core.js"),
    asset!("vendor/three/LICENSE"),
];

/// The embedded file at a URL path (`/` is `index.html`).
pub fn find(url_path: &str) -> Option<&'static Asset> {
    let rel = url_path.strip_prefix('/')?;
    let rel = if rel.is_empty() { "index.html" } else { rel };
    ASSETS.iter().find(|a| a.path == rel)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_and_everything_it_imports_are_embedded() {
        let index = find("/").map(|a| String::from_utf8_lossy(a.bytes).into_owned());
        let index = index.unwrap_or_default();
        // The import map names the vendored module, which imports its core beside it.
        assert!(index.contains("./vendor/three/three.module.js"), "{index}");
        let module = find("/vendor/three/three.module.js").map(|a| a.bytes);
        let module = String::from_utf8_lossy(module.unwrap_or_default());
        assert!(module.contains("from './three.core.js'"));
        assert!(find("/vendor/three/three.core.js").is_some_and(|a| a.bytes.len() > 100_000));
        assert!(find("/vendor/three/LICENSE").is_some_and(|a| a.bytes.starts_with(b"The MIT")));
        for script in ["main", "orbit", "organ", "plot", "colormap"] {
            assert!(find(&format!("/src/{script}.js")).is_some(), "{script}");
        }
        assert!(find("/../Cargo.toml").is_none() && find("/nothing.js").is_none());
    }
}
