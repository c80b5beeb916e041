//! The server over real sockets: static files stay under the root, and a WebSocket page that
//! sends malformed, binary or oversized messages gets errors back while its connection and
//! the command channel keep working.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

use tissue::Vec3;
use tungstenite::{Message, WebSocket};

use super::accept_loop;
use super::hub::Hub;
use super::messages::{Bounds, Command, MAX_MESSAGE_BYTES};

fn server() -> (u16, Arc<Hub>, Receiver<Command>) {
    let root = std::env::temp_dir().join(format!("tissue-view-test-{}", std::process::id()));
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(root.join("index.html"), "<p>hello</p>").unwrap_or_else(|e| panic!("{e}"));
    let listener = TcpListener::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let port = listener.local_addr().map(|a| a.port()).unwrap_or(0);
    let hub = Arc::new(Hub::default());
    hub.set_init(r#"{"type":"init"}"#.into());
    let (tx, rx) = channel();
    let bounds = Bounds {
        center: Vec3::ZERO,
        radius: 1.0,
    };
    let h = Arc::clone(&hub);
    std::thread::spawn(move || accept_loop(listener, root, h, tx, bounds));
    (port, hub, rx)
}

fn get(port: u16, path: &str) -> String {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap_or_else(|e| panic!("{e}"));
    write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap_or_else(|e| panic!("{e}"));
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    out
}

fn connect(port: u16) -> WebSocket<TcpStream> {
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap_or_else(|e| panic!("{e}"));
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap_or_else(|e| panic!("{e}"));
    let (ws, _) = tungstenite::client(format!("ws://127.0.0.1:{port}/ws"), s)
        .unwrap_or_else(|e| panic!("{e}"));
    ws
}

/// The next notice's text, skipping init and frame messages.
fn next_notice(ws: &mut WebSocket<TcpStream>) -> Option<String> {
    for _ in 0..100 {
        match ws.read() {
            Ok(Message::Text(t)) if t.as_str().contains("\"notice\"") => {
                return Some(t.as_str().to_string());
            }
            Ok(_) => {}
            Err(_) => return None,
        }
    }
    None
}

#[test]
fn static_files_stay_under_the_root() {
    let (port, _, _) = server();
    let ok = get(port, "/");
    assert!(
        ok.starts_with("HTTP/1.1 200 OK") && ok.ends_with("<p>hello</p>"),
        "{ok}"
    );
    assert!(get(port, "/../../etc/passwd").starts_with("HTTP/1.1 404"));
    assert!(get(port, "/.hidden").starts_with("HTTP/1.1 404"));
    assert!(get(port, "/missing.js").starts_with("HTTP/1.1 404"));
}

#[test]
fn bad_messages_get_errors_and_the_connection_goes_on() {
    let (port, hub, rx) = server();
    let mut ws = connect(port);
    let first = ws.read().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(first.to_text().unwrap_or(""), r#"{"type":"init"}"#);

    ws.send(Message::text("nonsense"))
        .unwrap_or_else(|e| panic!("{e}"));
    let n = next_notice(&mut ws).unwrap_or_default();
    assert!(n.contains("error") && n.contains("malformed"), "{n}");

    let big = format!(
        r#"{{"type":"reset","pad":"{}"}}"#,
        "x".repeat(MAX_MESSAGE_BYTES)
    );
    ws.send(Message::text(big))
        .unwrap_or_else(|e| panic!("{e}"));
    let n = next_notice(&mut ws).unwrap_or_default();
    assert!(n.contains("bytes rejected"), "{n}");

    ws.send(Message::binary(vec![1u8, 2, 3]))
        .unwrap_or_else(|e| panic!("{e}"));
    let n = next_notice(&mut ws).unwrap_or_default();
    assert!(n.contains("binary message of 3 bytes"), "{n}");

    // Still connected: a good command reaches the simulation side.
    ws.send(Message::text(r#"{"type":"reset"}"#))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rx.recv_timeout(Duration::from_secs(5)), Ok(Command::Reset));

    // Notices from the simulation reach the page.
    hub.notify("info", "hello page");
    let n = next_notice(&mut ws).unwrap_or_default();
    assert!(n.contains("hello page"), "{n}");

    // Past the transport cap the connection ends, with an error first...
    let huge = "y".repeat(2 * 1024 * 1024);
    let _ = ws.send(Message::text(huge));
    let n = next_notice(&mut ws).unwrap_or_default();
    assert!(n.contains("message rejected"), "{n}");
    // ...and the server still serves new pages.
    let mut again = connect(port);
    assert!(again.read().is_ok());
    assert!(get(port, "/").contains("hello"));
}
