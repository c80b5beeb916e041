//! `tissue view SCENE`: the interactive browser viewer. The simulation runs in this process
//! (`session`); a std `TcpListener` serves the page built into the binary (`assets`, or a
//! folder given by `--viewer-dir`) over HTTP (`http`) and upgrades `/ws` to a WebSocket
//! (`ws`) that carries JSON messages (`messages`); every request passes the session's
//! access rule first (`access`, docs/security.md). One thread per connection, one for the
//! simulation, one for the haptic loop.

mod access;
mod assets;
mod http;
mod hub;
mod messages;
mod publish;
mod session;
mod setup;
mod ws;

#[cfg(test)]
mod tests;

use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Args;
use tissue::scene::Scene;

use access::{Access, Grant};
use http::Pages;
use hub::Hub;
use session::Session;
use setup::Setup;

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The scene file (TOML): mesh, material, model, fixed regions. Its scripted
    /// instruments are replaced by the mouse-driven ones.
    pub scene: PathBuf,
    /// TCP port (0 picks a free one).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
    /// Address to listen on; anything but loopback exposes the simulation to the network
    /// (the session token in the printed URL is then all that guards it).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: IpAddr,
    /// Serve the page from this directory instead of the copy built into the binary
    /// (default: $TISSUE_VIEWER_DIR if set, else the built-in page).
    #[arg(long)]
    pub viewer_dir: Option<PathBuf>,
    /// Also listen for a haptic device on this UDP port (docs/haptic-protocol.md); it drives
    /// the probe.
    #[arg(long)]
    pub device_port: Option<u16>,
}

/// Connections served at once; more are refused (a page needs one or two).
const MAX_CONNECTIONS: usize = 32;

fn pages(args: &ViewArgs) -> anyhow::Result<Pages> {
    let dir = match &args.viewer_dir {
        Some(d) => d.clone(),
        None => match std::env::var_os("TISSUE_VIEWER_DIR") {
            Some(d) => PathBuf::from(d),
            None => return Ok(Pages::Embedded),
        },
    };
    if !dir.join("index.html").is_file() {
        bail!(
            "the viewer's page is missing: no {} (leave --viewer-dir and $TISSUE_VIEWER_DIR \
             unset to serve the page built into tissue)",
            dir.join("index.html").display()
        );
    }
    if !dir.join("vendor/three/three.module.js").is_file() {
        bail!(
            "three.js is missing from {}: copy viewer/vendor/ of the repository there",
            dir.join("vendor/three").display()
        );
    }
    Ok(Pages::Dir(dir))
}

/// Reads the request head without consuming it: `ws` needs it intact for its handshake.
fn peek_head(stream: &TcpStream) -> Option<String> {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let mut buf = vec![0u8; http::MAX_HEAD];
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(5) {
        let n = stream.peek(&mut buf).ok()?;
        if n == 0 {
            return None;
        }
        let got = buf.get(..n)?;
        if let Some(end) = got.windows(4).position(|w| w == b"\r\n\r\n") {
            return String::from_utf8(got.get(..end + 4)?.to_vec()).ok();
        }
        if n == buf.len() {
            return None; // head larger than the cap
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    None
}

pub fn view(args: &ViewArgs) -> anyhow::Result<()> {
    let root = pages(args)?;
    let scene = Scene::load(&args.scene)?;
    let (setup, material) = Setup::load(&scene)?;
    let hub = Arc::new(Hub::default());
    let device = args.device_port.map(|p| SocketAddr::new(args.host, p));
    let session = Session::new(setup, material, Arc::clone(&hub), device)
        .with_context(|| format!("building {}", args.scene.display()))?;
    let bounds = session.bounds();
    let listener = TcpListener::bind((args.host, args.port))
        .with_context(|| format!("cannot listen on {}:{}", args.host, args.port))?;
    let addr = listener.local_addr()?;
    let access = Access::random(args.host, addr.port())
        .context("cannot draw the session token from the system's random source")?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("tissue-view-sim".into())
        .spawn(move || session.run(rx))?;
    // An unspecified address (0.0.0.0, ::) is reached by whatever name: print loopback.
    let shown = if args.host.is_unspecified() {
        access::url_host(IpAddr::from([127, 0, 0, 1]))
    } else {
        access::url_host(args.host)
    };
    if !args.host.is_loopback() {
        eprintln!(
            "tissue view: warning: listening on {} (not loopback): anyone on the network \
             who has the URL's token can see the scene and drive it; every request must \
             carry the token and name {} (or a loopback name) as its Host",
            args.host, shown
        );
    }
    crate::outln!(
        "tissue view: http://{shown}:{}/?token={}  (Ctrl-C stops)",
        addr.port(),
        access.token()
    );
    accept_loop(listener, root, hub, tx, bounds, Arc::new(access));
    Ok(())
}

/// Serves connections until the listener fails: static files, or `/ws` upgrades.
fn accept_loop(
    listener: TcpListener,
    root: Pages,
    hub: Arc<Hub>,
    tx: Sender<messages::Command>,
    bounds: messages::Bounds,
    access: Arc<Access>,
) {
    let live = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        if live.load(Ordering::Relaxed) >= MAX_CONNECTIONS {
            continue; // dropped: closes the socket
        }
        live.fetch_add(1, Ordering::Relaxed);
        let (hub, tx, root, done, access) = (
            Arc::clone(&hub),
            tx.clone(),
            root.clone(),
            Arc::clone(&live),
            Arc::clone(&access),
        );
        let spawned = std::thread::Builder::new()
            .name("tissue-view-conn".into())
            .spawn(move || {
                let peer = stream
                    .peer_addr()
                    .map_or_else(|_| "?".to_string(), |a| a.to_string());
                if let Some(head) = peek_head(&stream) {
                    let ws_path = http::request_line(&head).is_some_and(|(_, p)| p == "/ws");
                    match access.check(&head) {
                        Err(e) => {
                            eprintln!("tissue view: {peer}: refused: {e}");
                            http::refuse(stream, &head, &e.to_string());
                        }
                        Ok(_) if ws_path && http::is_websocket(&head) => {
                            ws::serve(stream, peer, hub, tx, bounds);
                        }
                        Ok(grant) => {
                            let cookie = (grant == Grant::Query).then(|| access.set_cookie());
                            http::serve(stream, &head, &root, cookie.as_deref());
                        }
                    }
                }
                done.fetch_sub(1, Ordering::Relaxed);
            });
        if spawned.is_err() {
            live.fetch_sub(1, Ordering::Relaxed);
            eprintln!("tissue view: cannot start a connection thread");
        }
    }
}
