//! The UDP device bridge: a thread that receives pose datagrams from an external haptic
//! driver into the loop's pose slot, and a loop sink that sends every tick's force back to
//! the address the last good pose came from. Bad datagrams are counted and the last reason
//! kept; they never reach the pose slot.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::haptic::haptic_loop::{HapticHandle, Pose};
use crate::haptic::protocol::{ForcePacket, PosePacket};

/// Datagrams received by the bridge.
#[derive(Debug, Default)]
pub struct BridgeCounters {
    pub accepted: AtomicU64,
    pub rejected: AtomicU64,
    last_error: Mutex<Option<String>>,
}

impl BridgeCounters {
    /// Why the last bad datagram was rejected, with its sender.
    pub fn last_error(&self) -> Option<String> {
        self.last_error
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// A running bridge; `stop` (or drop) ends its thread and detaches its sink.
pub struct UdpBridge {
    addr: SocketAddr,
    counters: Arc<BridgeCounters>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    handle: HapticHandle,
}

impl UdpBridge {
    /// Binds `bind` (port 0 picks a free one) and connects it to the loop behind `handle`.
    pub fn start(bind: SocketAddr, handle: HapticHandle) -> std::io::Result<Self> {
        let socket = UdpSocket::bind(bind)?;
        // Short timeout: the thread notices `stop` within it.
        socket.set_read_timeout(Some(Duration::from_millis(20)))?;
        let addr = socket.local_addr()?;
        let sender = socket.try_clone()?;
        let peer: Arc<Mutex<Option<SocketAddr>>> = Arc::new(Mutex::new(None));
        let sink_peer = Arc::clone(&peer);
        handle.set_sink(Some(Box::new(move |sample| {
            let to = *sink_peer.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(to) = to {
                let packet = ForcePacket {
                    sequence: sample.sequence,
                    flags: 0,
                    force: sample.force,
                    tick: sample.tick,
                };
                // A device that went away is not the loop's problem: drop the datagram.
                let _ = sender.send_to(&packet.encode(), to);
            }
        })));
        let counters = Arc::new(BridgeCounters::default());
        let stop = Arc::new(AtomicBool::new(false));
        let (c, s, h) = (Arc::clone(&counters), Arc::clone(&stop), handle.clone());
        let thread = std::thread::Builder::new()
            .name("tissue-udp-bridge".into())
            .spawn(move || receive(&socket, &h, &c, &s, &peer))?;
        Ok(Self {
            addr,
            counters,
            stop,
            thread: Some(thread),
            handle,
        })
    }

    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn counters(&self) -> &BridgeCounters {
        &self.counters
    }

    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.handle.set_sink(None);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for UdpBridge {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn receive(
    socket: &UdpSocket,
    handle: &HapticHandle,
    counters: &BridgeCounters,
    stop: &AtomicBool,
    peer: &Mutex<Option<SocketAddr>>,
) {
    // Larger than any valid datagram, so an oversized one arrives long (or truncated to
    // this size) and fails the exact-length check.
    let mut buf = [0u8; 512];
    // Poses should reach the slot as soon as they arrive, like the loop's own ticks.
    crate::haptic::realtime::try_elevate();
    while !stop.load(Ordering::Relaxed) {
        let (n, from) = match socket.recv_from(&mut buf) {
            Ok(r) => r,
            Err(_) => continue, // timeout, or ICMP noise from a vanished peer
        };
        match PosePacket::decode(buf.get(..n).unwrap_or_default()) {
            Ok(p) => {
                counters.accepted.fetch_add(1, Ordering::Relaxed);
                *peer.lock().unwrap_or_else(|e| e.into_inner()) = Some(from);
                handle.set_pose(Pose {
                    position: p.position,
                    sequence: p.sequence,
                    flags: p.flags,
                });
            }
            Err(e) => {
                counters.rejected.fetch_add(1, Ordering::Relaxed);
                *counters
                    .last_error
                    .lock()
                    .unwrap_or_else(|e| e.into_inner()) = Some(format!("from {from}: {e}"));
            }
        }
    }
}
