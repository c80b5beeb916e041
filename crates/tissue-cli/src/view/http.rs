//! A small static-file HTTP/1.1 handler for the viewer's page: GET and HEAD only, one request
//! per connection, paths restricted to plain names under the viewer directory (no `..`, no
//! hidden files), a size cap on the request head.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};

/// Largest request head read, in bytes.
pub const MAX_HEAD: usize = 8 * 1024;

/// The request line's method and path, from a complete head.
pub fn request_line(head: &str) -> Option<(&str, &str)> {
    let line = head.lines().next()?;
    let mut parts = line.split(' ');
    let method = parts.next()?;
    let target = parts.next()?;
    let version = parts.next()?;
    if !version.starts_with("HTTP/1.") || parts.next().is_some() {
        return None;
    }
    Some((method, target.split(['?', '#']).next().unwrap_or(target)))
}

/// Whether the head asks for a WebSocket upgrade.
pub fn is_websocket(head: &str) -> bool {
    head.lines().skip(1).any(|l| {
        let l = l.to_ascii_lowercase();
        l.starts_with("upgrade:") && l.contains("websocket")
    })
}

/// Maps a URL path to a file under `root`; `None` for anything that is not a plain relative
/// path of safe characters.
pub fn resolve(root: &Path, url_path: &str) -> Option<PathBuf> {
    let rel = url_path.strip_prefix('/')?;
    let rel = if rel.is_empty() { "index.html" } else { rel };
    let mut out = root.to_path_buf();
    for part in rel.split('/') {
        let ok = !part.is_empty()
            && !part.starts_with('.')
            && part
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'));
        if !ok {
            return None;
        }
        out.push(part);
    }
    Some(out)
}

fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()).unwrap_or("") {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "json" | "map" => "application/json",
        "png" => "image/png",
        "svg" => "image/svg+xml",
        _ => "application/octet-stream",
    }
}

/// Extra headers for one response (a `Set-Cookie` line, or nothing).
type Extra<'a> = Option<&'a str>;

fn respond(
    stream: &mut TcpStream,
    status: &str,
    ctype: &str,
    body: &[u8],
    head_only: bool,
    cookie: Extra,
) {
    let cookie = cookie.map_or_else(String::new, |c| format!("Set-Cookie: {c}\r\n"));
    let header = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n{cookie}\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n\
         Referrer-Policy: no-referrer\r\nConnection: close\r\n\r\n",
        body.len()
    );
    // A page that went away mid-response is no error of ours.
    let _ = stream.write_all(header.as_bytes());
    if !head_only {
        let _ = stream.write_all(body);
    }
    let _ = stream.flush();
}

/// Consumes the peeked head so the socket closes cleanly.
fn consume(stream: &mut TcpStream, head: &str) {
    let mut sink = vec![0u8; head.len()];
    let _ = stream.read_exact(&mut sink);
}

/// Answers a request the access rule turned away: 403 with the reason.
pub fn refuse(mut stream: TcpStream, head: &str, reason: &str) {
    consume(&mut stream, head);
    let body = format!("forbidden: {reason}\n");
    respond(
        &mut stream,
        "403 Forbidden",
        "text/plain; charset=utf-8",
        body.as_bytes(),
        false,
        None,
    );
}

/// Where the page's files come from.
#[derive(Clone, Debug)]
pub enum Pages {
    /// Built into the binary (`assets`).
    Embedded,
    /// A folder (`--viewer-dir`): edit the page without rebuilding.
    Dir(PathBuf),
}

impl Pages {
    /// The file at a URL path and its name (for its content type).
    fn get(&self, url_path: &str) -> Option<(Vec<u8>, PathBuf)> {
        match self {
            Pages::Embedded => {
                super::assets::find(url_path).map(|a| (a.bytes.to_vec(), PathBuf::from(a.path)))
            }
            Pages::Dir(root) => {
                let file = resolve(root, url_path).filter(|p| p.is_file())?;
                std::fs::read(&file).ok().map(|b| (b, file))
            }
        }
    }
}

/// Reads the rest of the head (already peeked) and answers it; `cookie` is set on the
/// response when there is one.
pub fn serve(mut stream: TcpStream, head: &str, pages: &Pages, cookie: Extra) {
    consume(&mut stream, head);
    let Some((method, path)) = request_line(head) else {
        return respond(
            &mut stream,
            "400 Bad Request",
            "text/plain",
            b"bad request\n",
            false,
            None,
        );
    };
    let head_only = method == "HEAD";
    if method != "GET" && !head_only {
        return respond(
            &mut stream,
            "405 Method Not Allowed",
            "text/plain",
            b"only GET and HEAD\n",
            false,
            None,
        );
    }
    match pages.get(path) {
        Some((body, f)) => respond(
            &mut stream,
            "200 OK",
            content_type(&f),
            &body,
            head_only,
            cookie,
        ),
        None => respond(
            &mut stream,
            "404 Not Found",
            "text/plain",
            b"not found\n",
            head_only,
            None,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_stay_under_the_root() {
        let root = Path::new("/srv/viewer");
        assert_eq!(resolve(root, "/"), Some(root.join("index.html")));
        assert_eq!(
            resolve(root, "/node_modules/three/build/three.module.js"),
            Some(root.join("node_modules/three/build/three.module.js"))
        );
        for bad in [
            "/../etc/passwd",
            "/a/../../x",
            "/.git/config",
            "//etc",
            "/a%2f..",
            "/a\\b",
            "relative",
            "/a//b",
        ] {
            assert_eq!(resolve(root, bad), None, "{bad}");
        }
    }

    #[test]
    fn request_lines_and_upgrades() {
        let h = "GET /main.js?v=2 HTTP/1.1\r\nHost: x\r\n\r\n";
        assert_eq!(request_line(h), Some(("GET", "/main.js")));
        assert!(!is_websocket(h));
        assert!(is_websocket(
            "GET /ws HTTP/1.1\r\nConnection: Upgrade\r\nUpgrade: WebSocket\r\n\r\n"
        ));
        assert_eq!(request_line("GET /\r\n\r\n"), None);
        assert_eq!(request_line("GET / SPDY/3 extra\r\n"), None);
        assert_eq!(request_line(""), None);
    }
}
