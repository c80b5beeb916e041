//! The loop, the bridge and the emulator together over loopback UDP.

use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use super::*;
use crate::math::{Mat3, Vec3};

fn loopback() -> SocketAddr {
    ([127, 0, 0, 1], 0).into()
}

#[test]
fn emulator_feels_the_local_model_through_the_bridge() {
    let lp = HapticLoop::start(HapticConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let h = lp.handle();
    // A wall at y = 0 with 100 N/m, anchored where the contact force is 0.5 N.
    h.update_contact(Vec3::new(0.0, -0.005, 0.0), Vec3::new(0.0, 0.5, 0.0), true);
    h.set_stiffness(Mat3::from_diagonal(Vec3::splat(-100.0)));
    let bridge = UdpBridge::start(loopback(), h.clone()).unwrap_or_else(|e| panic!("{e}"));
    // The device presses from y = 0 (0 N) to y = -0.01 m (1 N) in 0.2 s.
    let path = |t: f64| Vec3::new(0.0, -0.05 * t.min(0.2), 0.0);
    let rep =
        run_emulator(bridge.local_addr(), 0.25, 1000.0, &path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rep.poses_sent, 250);
    assert_eq!(rep.bad_datagrams, 0);
    assert_eq!(
        bridge
            .counters()
            .rejected
            .load(std::sync::atomic::Ordering::Relaxed),
        0
    );
    // The loop answers every tick once it knows the device: about as many forces as poses.
    assert!(rep.forces_received > 150, "{rep:?}");
    // Max force: 0.5 + 100 * 0.005 = 1.0 N at the deepest point.
    assert!((rep.max_force - 1.0).abs() < 1e-9, "{rep:?}");
    assert!((rep.last_force.y - 1.0).abs() < 1e-9, "{rep:?}");
    assert!(
        rep.round_trip.ticks > 100 && rep.round_trip.p50_us < 5000.0,
        "{rep:?}"
    );
    bridge.stop();
    let stats = lp.stop();
    assert!(stats.ticks > 150);
}

#[test]
fn bridge_rejects_malformed_datagrams_and_keeps_the_pose() {
    let lp = HapticLoop::start(HapticConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let h = lp.handle();
    let bridge = UdpBridge::start(loopback(), h.clone()).unwrap_or_else(|e| panic!("{e}"));
    let dev = UdpSocket::bind(loopback()).unwrap_or_else(|e| panic!("{e}"));
    let good = PosePacket {
        sequence: 9,
        flags: 0,
        position: Vec3::new(0.1, 0.2, 0.3),
        orientation: [1.0, 0.0, 0.0, 0.0],
    }
    .encode();
    let mut nan = good.clone();
    nan[12..20].copy_from_slice(&f64::NAN.to_le_bytes());
    let bad: Vec<Vec<u8>> = vec![
        vec![],
        b"hello".to_vec(),
        vec![0u8; 2000],
        good[..40].to_vec(),
        nan,
    ];
    dev.send_to(&good, bridge.local_addr())
        .unwrap_or_else(|e| panic!("{e}"));
    for b in &bad {
        dev.send_to(b, bridge.local_addr())
            .unwrap_or_else(|e| panic!("{e}"));
    }
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    let c = bridge.counters();
    use std::sync::atomic::Ordering::Relaxed;
    while c.accepted.load(Relaxed) + c.rejected.load(Relaxed) < 6 {
        assert!(std::time::Instant::now() < deadline, "datagrams lost");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(c.accepted.load(Relaxed), 1);
    assert_eq!(c.rejected.load(Relaxed), 5);
    assert!(c.last_error().is_some_and(|e| e.contains("position")));
    let p = h.pose();
    assert_eq!((p.sequence, p.position), (9, Vec3::new(0.1, 0.2, 0.3)));
    // The device gets force datagrams back for its pose.
    dev.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut buf = [0u8; 128];
    let (n, _) = dev.recv_from(&mut buf).unwrap_or_else(|e| panic!("{e}"));
    let f = ForcePacket::decode(&buf[..n]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((f.sequence, f.force), (9, Vec3::ZERO));
    bridge.stop();
    lp.stop();
}

/// `step_coupled` hands the loop the model's own stiffness (here `bem`'s, for a grasper on
/// a sphere), symmetrised, instead of a secant estimate.
#[test]
fn a_coupled_step_gives_the_loop_the_models_stiffness() {
    use crate::interact::{Instrument, InstrumentKind, Loads, Trajectory};
    use crate::material::Material;
    use crate::mesh::generate::icosphere;
    use crate::model::bem::{Bem, BemParams};
    use crate::sim::Simulation;

    let s = icosphere(Vec3::ZERO, 0.05, 2);
    let fixed = (0..s.vertices.len() as u32)
        .filter(|&v| s.vertices[v as usize].z < -0.03)
        .collect();
    let model = Bem::new(
        &s,
        Material::new(3000.0, 0.3).unwrap(),
        BemParams::default(),
    )
    .unwrap();
    let mut sim = Simulation::new(Box::new(model), fixed, Loads::default()).unwrap();
    let at = Vec3::new(0.0, 0.0, 0.05);
    let grasp = InstrumentKind::Grasper {
        grasp_at: 0.0,
        release_at: None,
    };
    sim.add_instrument(Instrument::new("grasper", grasp, 0.02, Trajectory::fixed(at)).unwrap());
    let lp = HapticLoop::start(HapticConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let h = lp.handle();
    for depth in [0.0, 1e-3, 2e-3] {
        h.set_pose(Pose {
            position: at - Vec3::Z * depth,
            ..Pose::default()
        });
        step_coupled(&mut sim, 0, &h, 0.01).unwrap();
    }
    let k = sim.instrument_stiffness(0).unwrap();
    let sym = (k + k.transpose()) * 0.5;
    let gap = (h.stiffness() - sym)
        .to_cols_array()
        .iter()
        .fold(0.0, |a: f64, b| a.max(b.abs()));
    assert!(
        gap <= 1e-9 * sym.z_axis.z.abs(),
        "{:?} vs {sym:?}",
        h.stiffness()
    );
    assert!(sym.z_axis.z < 0.0);
    lp.stop();
}
