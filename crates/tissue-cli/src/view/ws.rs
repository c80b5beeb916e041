//! One page connection over WebSocket (tungstenite, blocking with a short read timeout): it
//! forwards checked commands to the simulation thread and sends the hub's newest init,
//! frame and notices. A bad message gets an error back and a log line; the connection and
//! the simulation go on. A message past the transport cap ends only this connection.

use std::net::TcpStream;
use std::sync::Arc;
use std::sync::mpsc::Sender;
use std::time::Duration;

use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

use super::hub::{Hub, notice_json};
use super::messages::{Bounds, Command, MAX_MESSAGE_BYTES, parse};

/// Frames larger than this are refused by the transport itself (the connection closes);
/// between `MAX_MESSAGE_BYTES` and this, the message is read and rejected politely.
const TRANSPORT_CAP: usize = 1024 * 1024;

fn send(ws: &mut WebSocket<TcpStream>, text: &str) -> bool {
    ws.send(Message::text(text.to_string())).is_ok()
}

/// Serves one upgraded connection until the page closes it.
pub fn serve(
    stream: TcpStream,
    peer: String,
    hub: Arc<Hub>,
    commands: Sender<Command>,
    bounds: Bounds,
) {
    let config = WebSocketConfig::default()
        .max_message_size(Some(TRANSPORT_CAP))
        .max_frame_size(Some(TRANSPORT_CAP));
    let mut ws = match tungstenite::accept_with_config(stream, Some(config)) {
        Ok(ws) => ws,
        Err(e) => return eprintln!("tissue view: {peer}: WebSocket handshake failed: {e}"),
    };
    let _ = ws
        .get_ref()
        .set_read_timeout(Some(Duration::from_millis(10)));
    let _ = ws.get_ref().set_write_timeout(Some(Duration::from_secs(5)));
    eprintln!("tissue view: page connected from {peer}");
    let (mut init_seen, mut frame_seen) = (0, 0);
    let mut notice_seen = hub.last_notice();
    loop {
        match ws.read() {
            Ok(Message::Text(t)) => match parse(t.as_str(), &bounds) {
                Ok(c) => {
                    if commands.send(c).is_err() {
                        break; // the simulation thread is gone: the server is stopping
                    }
                }
                Err(e) => {
                    eprintln!("tissue view: {peer}: rejected a message: {e}");
                    if !send(&mut ws, &notice_json("error", &e)) {
                        break;
                    }
                }
            },
            Ok(Message::Binary(b)) => {
                let e = format!(
                    "binary message of {} bytes rejected: send JSON text",
                    b.len()
                );
                eprintln!("tissue view: {peer}: {e}");
                if !send(&mut ws, &notice_json("error", &e)) {
                    break;
                }
            }
            Ok(Message::Close(_)) => break,
            Ok(_) => {} // ping/pong are answered by tungstenite
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(tungstenite::Error::Capacity(e)) => {
                let e = format!(
                    "message rejected: {e} (limit {MAX_MESSAGE_BYTES} bytes); reconnecting"
                );
                eprintln!("tissue view: {peer}: {e}");
                let _ = send(&mut ws, &notice_json("error", &e));
                break;
            }
            Err(_) => break,
        }
        let init = hub.init();
        if init.version != init_seen {
            init_seen = init.version;
            if !send(&mut ws, &init.text) {
                break;
            }
        }
        let frame = hub.frame();
        if frame.version != frame_seen {
            frame_seen = frame.version;
            if !send(&mut ws, &frame.text) {
                break;
            }
        }
        let (notices, last) = hub.notices_since(notice_seen);
        notice_seen = last;
        if notices.iter().any(|n| !send(&mut ws, n)) {
            break;
        }
    }
    eprintln!("tissue view: page from {peer} disconnected");
}
