//! Background rim solves (`background_rim_solves`): while the worker solves, the contacts
//! are exactly the continuous rule's; once the pairs land the result is the blocking
//! rule's, bit for bit.

use super::tests::{material, press, sphere, step, top};
use super::*;
use crate::interact::Constraints;
use crate::math::{Real, Vec3};
use crate::model::Deformable;

fn params(background: bool) -> BemParams {
    BemParams {
        discontinuous_contacts: true,
        background_rim_solves: Some(background),
        ..BemParams::default()
    }
}

/// x = u_L + W_{:,C} P_C straight from the system (no landing of background solves).
fn static_solution(m: &Bem, c: &Constraints) -> Vec<Real> {
    let sys = m.system();
    let targets: Vec<Vec3> = c
        .prescribed
        .iter()
        .map(|p| p.position - m.rest_surface()[p.vertex as usize])
        .collect();
    let u_load = vec![0.0; sys.dofs()];
    let mut x = vec![0.0; sys.dofs()];
    let mut p = vec![0.0; 3 * targets.len()];
    sys.solve(&targets, &u_load, &mut x, &mut p).unwrap();
    x
}

#[test]
fn background_rim_solves_start_continuous_and_end_as_the_blocking_rule() {
    let s = sphere(2);
    let rest = s.vertices.clone();
    let top = top(&rest);
    let first = press(&rest, -0.03, &top[..16]);
    let second = press(&rest, -0.03, &top[6..24]);

    let mut blocking = Bem::new(&s, material(), params(false)).unwrap();
    let blocking_first = step(&mut blocking, &first);
    let blocking_second = step(&mut blocking, &second);
    let mut continuous = Bem::new(&s, material(), BemParams::continuous()).unwrap();
    continuous.set_constraints(&first).unwrap();

    // Cold: the contacts wait on the continuous rule, exactly the default model's. A thread
    // per core (three asked, no more than the cores), so that batches may land out of order.
    let mut m = Bem::new(&s, material(), params(true)).unwrap();
    m.set_rim_solve_threads(3);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert_eq!(m.system().rim_threads(), cores.min(3));
    m.set_constraints(&first).unwrap();
    assert!(m.system().contacts_waiting_for_rims());
    assert!(m.system().pending_rim_solves() > 0);
    assert!(static_solution(&m, &first) == static_solution(&continuous, &first));
    for p in &first.prescribed {
        let v = p.vertex as usize;
        let area = m.system().support_area(v).unwrap();
        assert!((area - m.areas()[v]).abs() <= 1e-12 * area, "{area}");
    }

    // Finished: the blocking rule's step, bit for bit.
    m.finish_contact_rims().unwrap();
    assert!(!m.system().contacts_waiting_for_rims());
    assert!(step(&mut m, &first) == blocking_first);

    // Partly cached: still the continuous rule until every pair is there.
    m.set_constraints(&second).unwrap();
    continuous.set_constraints(&second).unwrap();
    eprintln!(
        "second set: {} pairs to solve",
        m.system().pending_rim_solves()
    );
    assert!(m.system().contacts_waiting_for_rims());
    assert!(static_solution(&m, &second) == static_solution(&continuous, &second));

    // Landing while stepping: the steps switch the contacts over by themselves.
    let start = std::time::Instant::now();
    let mut steps = 0;
    while m.system().contacts_waiting_for_rims() {
        assert!(
            start.elapsed().as_secs() < 60,
            "the background solves never landed"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
        m.step(0.01).unwrap();
        steps += 1;
    }
    eprintln!("landed after {steps} steps");
    assert!(step(&mut m, &second) == blocking_second);
    assert_eq!(m.system().factorizations, 1);
}

#[test]
fn a_new_factorisation_drops_the_rim_solves_in_flight() {
    // Pairs solved for the old A₀ must never reach the cache of the new one.
    let s = sphere(2);
    let rest = s.vertices.clone();
    let top = top(&rest);
    let old = press(&rest, -0.03, &top[..16]);
    let new = press(&rest, -0.02, &top[..16]);
    let mut m = Bem::new(&s, material(), params(true)).unwrap();
    m.set_constraints(&old).unwrap();
    assert!(m.system().pending_rim_solves() > 0);
    m.set_constraints(&new).unwrap();
    assert_eq!(m.system().factorizations, 2);
    m.finish_contact_rims().unwrap();
    // Both contact sets need the same pairs: a q solved for the old A₀ that reached the
    // new cache would be used here and change the bits.
    let mut blocking = Bem::new(&s, material(), params(false)).unwrap();
    assert!(step(&mut m, &new) == step(&mut blocking, &new));
    assert!(m.system().rim_cache_usage().1 >= blocking.system().rim_cache_usage().1);
}

/// Steps until the worker has nothing left to solve (or a minute has gone by).
fn settle(m: &mut Bem) {
    let start = std::time::Instant::now();
    while m.system().pending_rim_solves() > 0 {
        assert!(start.elapsed().as_secs() < 60, "the worker never finished");
        std::thread::sleep(std::time::Duration::from_millis(2));
        m.step(0.01).unwrap();
    }
    m.step(0.01).unwrap();
}

#[test]
fn real_time_follows_the_driver_unless_the_scene_chose() {
    let s = sphere(2);
    let rest = s.vertices.clone();
    let first = press(&rest, -0.03, &top(&rest)[..8]);
    // Unset: blocking until the driver says it runs against the clock.
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    assert!(m.params().discontinuous_contacts);
    m.set_real_time(true);
    m.set_constraints(&first).unwrap();
    assert!(m.system().contacts_waiting_for_rims());
    // Chosen off: the driver does not override it.
    let mut chosen = Bem::new(&s, material(), params(false)).unwrap();
    chosen.set_real_time(true);
    chosen.set_constraints(&first).unwrap();
    assert!(!chosen.system().contacts_waiting_for_rims());
    assert_eq!(chosen.system().pending_rim_solves(), 0);
}

#[test]
fn real_time_solves_ahead_of_a_growing_patch() {
    // While the probe rests, the worker solves the rim pairs on both sides of the patch's
    // edge, so the next, larger patch switches to its rims at once, with the bits the
    // blocking rule gives it.
    let s = sphere(2);
    let rest = s.vertices.clone();
    let top = top(&rest);
    let first = press(&rest, -0.03, &top[..8]);
    let grown = press(&rest, -0.03, &top[..14]);
    let mut blocking = Bem::new(&s, material(), BemParams::default()).unwrap();
    blocking.set_constraints(&first).unwrap();
    let (needed, _) = blocking.system().rim_cache_counts();
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    m.set_real_time(true);
    m.set_constraints(&first).unwrap();
    settle(&mut m);
    let (solved, _) = m.system().rim_cache_counts();
    eprintln!("first patch: {needed} pairs needed, {solved} solved with those ahead");
    assert!(solved > needed, "{solved} {needed}");
    assert!(!m.system().contacts_waiting_for_rims());
    m.set_constraints(&grown).unwrap();
    assert!(
        !m.system().contacts_waiting_for_rims(),
        "the grown patch's rims were not solved ahead"
    );
    assert!(step(&mut m, &grown) == step(&mut blocking, &grown));
}
