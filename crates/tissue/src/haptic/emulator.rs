//! A scripted haptic device: sends poses along a path at a fixed rate over UDP and reads the
//! forces coming back, like a driver of a real device would. Used by the tests and by
//! `tissue haptic-bench`.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use crate::haptic::protocol::{ForcePacket, PosePacket};
use crate::haptic::stats::{TimingStats, TimingSummary};
use crate::math::{Real, Vec3};

/// What the emulated device saw.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EmulatorReport {
    pub poses_sent: u64,
    pub forces_received: u64,
    /// Force datagrams that failed to decode.
    pub bad_datagrams: u64,
    pub max_force: Real,
    pub last_force: Vec3,
    /// From sending a pose to receiving the first force computed for it.
    pub round_trip: TimingSummary,
}

/// Sends `seconds * rate_hz` poses along `path(t)` to the bridge at `target`.
pub fn run_emulator(
    target: SocketAddr,
    seconds: Real,
    rate_hz: Real,
    path: &dyn Fn(Real) -> Vec3,
) -> std::io::Result<EmulatorReport> {
    let bind: SocketAddr = if target.is_ipv4() {
        ([127, 0, 0, 1], 0).into()
    } else {
        (std::net::Ipv6Addr::LOCALHOST, 0).into()
    };
    let socket = UdpSocket::bind(bind)?;
    socket.set_nonblocking(true)?;
    // A device driver runs its servo thread at real-time priority; so does the emulator
    // (this thread only), so that the round trip measures the bridge, not the scheduler.
    crate::haptic::realtime::try_elevate();
    let period = Duration::from_secs_f64(1.0 / rate_hz.clamp(1.0, 1e5));
    let count = (seconds.max(0.0) * rate_hz.clamp(1.0, 1e5)).round() as u64;
    // Send times by sequence number modulo the ring size (older answers are ignored).
    const RING: usize = 4096;
    let mut sent_at: Vec<Option<(u32, Instant)>> = vec![None; RING];
    let mut rtt = TimingStats::new(period);
    let mut report = EmulatorReport::default();
    let start = Instant::now();
    let mut buf = [0u8; 512];
    for k in 0..count {
        let due = start + period * u32::try_from(k).unwrap_or(u32::MAX);
        while Instant::now() < due {
            drain(&socket, &mut buf, &mut sent_at, &mut rtt, &mut report);
            std::thread::sleep(Duration::from_micros(100));
        }
        let sequence = k as u32;
        let pose = PosePacket {
            sequence,
            flags: 0,
            position: path(k as Real / rate_hz),
            orientation: [1.0, 0.0, 0.0, 0.0],
        };
        if let Some(slot) = sent_at.get_mut(sequence as usize % RING) {
            *slot = Some((sequence, Instant::now()));
        }
        socket.send_to(&pose.encode(), target)?;
        report.poses_sent += 1;
    }
    // Let the last answers arrive.
    let end = Instant::now() + Duration::from_millis(20);
    while Instant::now() < end {
        drain(&socket, &mut buf, &mut sent_at, &mut rtt, &mut report);
        std::thread::sleep(Duration::from_micros(200));
    }
    rtt.set_elapsed(start.elapsed());
    report.round_trip = rtt.summary();
    Ok(report)
}

fn drain(
    socket: &UdpSocket,
    buf: &mut [u8],
    sent_at: &mut [Option<(u32, Instant)>],
    rtt: &mut TimingStats,
    report: &mut EmulatorReport,
) {
    while let Ok((n, _)) = socket.recv_from(buf) {
        let now = Instant::now();
        match ForcePacket::decode(buf.get(..n).unwrap_or_default()) {
            Ok(f) => {
                report.forces_received += 1;
                report.last_force = f.force;
                report.max_force = report.max_force.max(f.force.length());
                let len = sent_at.len().max(1);
                if let Some(slot) = sent_at.get_mut(f.sequence as usize % len)
                    && let Some((seq, t)) = *slot
                    && seq == f.sequence
                {
                    rtt.record(now - t);
                    *slot = None;
                }
            }
            Err(_) => report.bad_datagrams += 1,
        }
    }
}
