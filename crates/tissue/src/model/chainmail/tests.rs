//! ChainMail checks: exact propagation distances, limits after propagation, rigid motion,
//! locality, relaxation to rest, per-voxel limits, cut / carve / join, the model on a liver.

use super::*;
use crate::interact::{Constraints, Prescribed};
use crate::mesh::MeshData;
use crate::model::{CutPath, Deformable};
use crate::voxel::boundary::closed_pieces;

const H: Real = 0.01;

fn block(dims: [usize; 3]) -> (VoxelGrid, Lattice) {
    let g = VoxelGrid::filled(dims, H);
    let l = Lattice::new(&g, &[ChainMailParams::default().limits(); 2]);
    (g, l)
}

fn displaced(l: &Lattice) -> usize {
    (0..l.len()).filter(|&v| l.x[v] != l.rest[v]).count()
}

#[test]
fn a_pushed_face_moves_exactly_the_layers_the_slack_cannot_absorb() {
    // Compression 0.9: each x-link absorbs 0.1 h. Pushing the x = 0 face by 0.35 h moves
    // layer j by 0.35 h - 0.1 h j: layers 1, 2, 3 (3 x 9 elements), nothing beyond.
    let (g, mut l) = block([20, 3, 3]);
    let d = 0.35 * H;
    let face: Vec<(u32, Vec3)> = (0..g.len())
        .filter(|&v| g.coords(v)[0] == 0)
        .map(|v| (v as u32, l.rest[v] + Vec3::X * d))
        .collect();
    let p = l.move_elements(&face);
    assert!(p.converged);
    assert_eq!(p.moved, 27);
    for v in 0..g.len() {
        let i = g.coords(v)[0] as Real;
        let expect = (d - 0.1 * H * i).max(0.0);
        let got = l.x[v] - l.rest[v];
        assert!(
            (got.x - expect).abs() < 1e-15 && got.y == 0.0 && got.z == 0.0,
            "{v}"
        );
    }
    assert_eq!(displaced(&l), 9 + 27);
    assert!(l.violated_links(1e-15).is_empty());
}

#[test]
fn after_propagation_every_link_holds_and_only_violated_elements_moved() {
    let (g, mut l) = block([16, 16, 16]);
    let centre = g.index(8, 8, 15).unwrap();
    let moves = [
        Vec3::new(0.0, 0.0, -0.8 * H),
        Vec3::new(1.2 * H, -0.7 * H, -0.6 * H),
        Vec3::new(0.0, 0.0, 2.5 * H),
    ];
    let mut total = 0;
    for m in moves {
        l.unpin_all();
        let p = l.move_elements(&[(centre as u32, l.x[centre] + m)]);
        assert!(p.converged);
        assert!(p.moved > 0 && p.moved < l.len(), "{}", p.moved);
        assert!(l.violated_links(1e-12).is_empty());
        total += p.moved;
        let _ = total;
    }
    // A move inside the free range of every link moves nothing and checks only the 6 links.
    let (_, mut l2) = block([5, 5, 5]);
    let p = l2.move_elements(&[(62, l2.rest[62] + Vec3::new(0.05, -0.05, 0.08) * H)]);
    assert_eq!((p.moved, p.checks), (0, 6));
    assert_eq!(displaced(&l2), 1);
    // Elements never moved by the wave are exactly at rest.
    let (_, mut l3) = block([12, 12, 12]);
    let c = 12 * 12 * 6 + 12 * 6 + 6;
    let p = l3.move_elements(&[(c as u32, l3.rest[c] + Vec3::new(0.0, 0.0, 1.5 * H))]);
    assert_eq!(displaced(&l3), p.moved + 1);
}

#[test]
fn moving_everything_rigidly_leaves_every_link_unchanged() {
    let (g, mut l) = block([6, 5, 4]);
    let t = Vec3::new(0.37, -1.1, 2.3) * H;
    let all: Vec<(u32, Vec3)> = (0..g.len()).map(|v| (v as u32, l.rest[v] + t)).collect();
    let p = l.move_elements(&all);
    assert_eq!(p.moved, 0);
    for a in 0..l.len() {
        for d in 0..6 {
            if let Some(b) = l.neighbour(a, d) {
                let now = l.x[b] - l.x[a];
                let rest = l.rest[b] - l.rest[a];
                assert!((now - rest).length() < 1e-15);
            }
        }
    }
    // Relaxation keeps a rigidly moved free body where it is.
    l.unpin_all();
    assert!(l.relax(10, 0.5) < 1e-15);
}

#[test]
fn relaxation_returns_to_rest_and_leaves_an_undisturbed_body_alone() {
    let (g, mut l) = block([8, 4, 4]);
    assert_eq!(l.relax(5, 0.5), 0.0);
    assert!(l.active().is_empty());
    let fixed: Vec<(u32, Vec3)> = (0..g.len())
        .filter(|&v| g.coords(v)[0] == 0)
        .map(|v| (v as u32, l.rest[v]))
        .collect();
    let pushed: Vec<(u32, Vec3)> = (0..g.len())
        .filter(|&v| g.coords(v)[0] == 7)
        .map(|v| (v as u32, l.rest[v] - Vec3::new(0.4 * H, 0.2 * H, 0.0)))
        .collect();
    l.move_elements(&fixed);
    l.move_elements(&pushed);
    assert!(displaced(&l) > 16);
    l.unpin_all();
    l.move_elements(&fixed);
    let mut sweeps = 0;
    while !l.active().is_empty() && sweeps < 20000 {
        l.relax(10, 1.0);
        sweeps += 10;
    }
    assert!(l.active().is_empty(), "still active after {sweeps} sweeps");
    assert_eq!(displaced(&l), 0);
}

#[test]
fn per_voxel_limits_carry_a_push_further_through_stiff_voxels() {
    // Stiff class 2 (compression 0.98: 0.02 h of slack per link), soft class 1 (0.5).
    let mut g = VoxelGrid::filled([20, 1, 1], H);
    for i in 0..10 {
        g.labels[i] = 2;
    }
    let soft = Limits {
        compression: 0.5,
        stretch: 1.5,
        shear: 0.5,
    };
    let stiff = Limits {
        compression: 0.98,
        stretch: 1.02,
        shear: 0.02,
    };
    let mut l = Lattice::new(&g, &[soft, soft, stiff]);
    let p = l.move_elements(&[(0, l.rest[0] + Vec3::X * 0.1 * H)]);
    // 0.1 h - 0.02 h j > 0 for j = 1..4.
    assert_eq!(p.moved, 4);
    assert!((l.x[4].x - l.rest[4].x - 0.02 * H).abs() < 1e-15);
    // The same push from the soft end moves nothing.
    let p = l.move_elements(&[(19, l.rest[19] - Vec3::X * 0.1 * H)]);
    assert_eq!(p.moved, 0);
    // A mixed link gets the mean of the two halves: (0.98 + 0.5) / 2 = 0.74 h.
    let mut l2 = Lattice::new(&g, &[soft, soft, stiff]);
    l2.move_elements(&[(9, l2.rest[9] + Vec3::X * 0.5 * H)]);
    assert!((l2.x[10].x - l2.x[9].x - 0.74 * H).abs() < 1e-15);
}

#[test]
fn two_instruments_push_from_both_sides() {
    let (g, mut l) = block([12, 12, 12]);
    let a = g.index(6, 6, 0).unwrap();
    let b = g.index(6, 6, 11).unwrap();
    let p = l.move_elements(&[
        (a as u32, l.rest[a] + Vec3::Z * 0.5 * H),
        (b as u32, l.rest[b] - Vec3::Z * 0.5 * H),
    ]);
    assert!(p.converged);
    assert!(l.violated_links(1e-12).is_empty());
    assert!(l.x[g.index(6, 6, 1).unwrap()].z > l.rest[g.index(6, 6, 1).unwrap()].z);
    assert!(l.x[g.index(6, 6, 10).unwrap()].z < l.rest[g.index(6, 6, 10).unwrap()].z);
}

fn cube_model(n: usize) -> ChainMail {
    let g = VoxelGrid::filled([n, n, n], H);
    ChainMail::new(
        g,
        None,
        Material::new(3000.0, 0.3).unwrap(),
        ChainMailParams::default(),
    )
    .unwrap()
}

#[test]
fn cut_carve_and_join_edit_the_links_and_the_surface_follows() {
    let mut m = cube_model(6);
    let links = m.lattice().link_count();
    assert_eq!(links, 3 * 5 * 36);
    let tris = m.surface().triangles.len();
    // A blade sweeping the plane x = 2.5 h through the whole block.
    let x = 2.5 * H;
    let blade = CutPath {
        start: [Vec3::new(x, -H, -H), Vec3::new(x, 7.0 * H, -H)],
        end: [Vec3::new(x, -H, 7.0 * H), Vec3::new(x, 7.0 * H, 7.0 * H)],
    };
    let info = m.cut(&blade).unwrap();
    assert_eq!(info.removed_elements, 36);
    assert_eq!(m.lattice().link_count(), links - 36);
    // The drawn surface: two closed boxes (χ = 2 each), lips included.
    let s = m.surface();
    assert_ne!(s.triangles.len(), tris);
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2, 2]
    );
    // The two halves are free of each other: pulling one leaves the other at rest.
    let near: Vec<u32> = (0..m.lattice().len() as u32)
        .filter(|&v| v % 6 < 3)
        .collect();
    let mut l = m.lattice.clone();
    let moves: Vec<(u32, Vec3)> = near
        .iter()
        .map(|&v| (v, l.rest[v as usize] - Vec3::X * H))
        .collect();
    l.move_elements(&moves);
    assert!(
        (0..l.len())
            .filter(|v| v % 6 >= 3)
            .all(|v| l.x[v] == l.rest[v])
    );
    // Moving the near half rigidly by −h: its piece of surface (lip included) follows
    // exactly, the far piece stays; the surface stays closed.
    let rigid: Vec<(u32, Vec3)> = near
        .iter()
        .map(|&v| (v, l.rest[v as usize] - Vec3::X * H))
        .collect();
    m.lattice.move_elements(&rigid);
    m.refresh_surface();
    let s = m.surface();
    for &v in s.triangles.iter().flatten() {
        let (p, r) = (s.positions[v as usize], m.embedding.rest[v as usize]);
        let (ids, w) = (
            m.embedding.nodes[v as usize],
            m.embedding.weights[v as usize],
        );
        let sides: Vec<bool> = (0..8)
            .filter(|&k| w[k] != 0.0)
            .map(|k| ids[k] % 6 < 3)
            .collect();
        // Every vertex follows one side only (the lips are apart at the cut).
        assert!(sides.iter().all(|&x| x == sides[0]), "{v}");
        if sides[0] {
            assert!((p - r + Vec3::X * H).length() < 1e-15, "{v}");
        } else {
            assert_eq!(p, r);
        }
    }
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2, 2]
    );
    m.lattice.unpin_all();
    Deformable::reset(&mut m);
    // Joining touching elements restores exactly the cut links.
    assert_eq!(m.join(1e-12), 36);
    assert_eq!(m.lattice().link_count(), links);
    let s = m.surface();
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2]
    );
    // Carving a ball of radius 1.1 h around a corner voxel removes it and its 3 neighbours.
    let removed = m.carve(Vec3::ZERO, 1.1 * H).unwrap();
    assert_eq!(removed, 4);
    // Its 3 links and 3 more of each neighbour.
    assert_eq!(m.lattice().link_count(), links - 12);
    let s = m.surface();
    assert_eq!(
        closed_pieces(s.triangles, s.positions, 1e-8 * H * H).unwrap(),
        vec![2]
    );
    assert!(m.carve(Vec3::NAN, 1.0).is_err());
}

#[test]
fn the_liver_is_pressed_released_and_returns() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver-smooth.obj"
    );
    let mut mesh: MeshData = crate::io::read(path).unwrap();
    for v in &mut mesh.vertices {
        *v *= 0.01;
    }
    let params: toml::Table =
        toml::from_str("resolution = 16\nrelax_iterations = 20\nrelax_rate = 1.0").unwrap();
    let input = BuildInput {
        mesh: &mesh,
        source: path,
        material: Material::new(3000.0, 0.3).unwrap(),
        params: &params,
        regions: &[],
    };
    let mut m = ChainMail::from_input(&input).unwrap();
    let rest = m.rest_surface().to_vec();
    // The topmost vertex is pressed 5 mm down; the lowest 50 vertices are fixed.
    let top = (0..rest.len())
        .max_by(|&a, &b| rest[a].y.total_cmp(&rest[b].y))
        .unwrap();
    let mut order: Vec<usize> = (0..rest.len()).collect();
    order.sort_by(|&a, &b| rest[a].y.total_cmp(&rest[b].y));
    let fixed: Vec<u32> = order[..50].iter().map(|&v| v as u32).collect();
    let target = rest[top] - Vec3::Y * 0.005;
    m.set_constraints(&Constraints {
        fixed: fixed.clone(),
        prescribed: vec![Prescribed {
            vertex: top as u32,
            position: target,
        }],
    })
    .unwrap();
    m.step(0.01).unwrap();
    assert!(m.surface().positions[top].distance(target) < 1e-12);
    assert!(m.last_propagation().converged && m.last_propagation().moved > 0);
    assert!(m.lattice().violated_links(1e-12).is_empty());
    let f = m.reactions().prescribed[0];
    let gained = m.rest_depth(target) - m.rest_depth(rest[top]);
    let expect = m.force_stiffness * gained.abs() * m.vertex_area[top];
    assert!(f.y > 0.0 && (f.length() - expect).abs() < 1e-12 * expect.max(1e-300));
    assert!(m.rest_depth(target) > 0.002);
    // Released: relaxation brings it back to rest.
    m.set_constraints(&Constraints::fixed(fixed)).unwrap();
    let mut steps = 0;
    while steps < 3000 && !m.lattice().active().is_empty() {
        m.step(0.01).unwrap();
        steps += 1;
    }
    assert!(steps < 3000, "{steps}");
    let worst = m
        .surface()
        .positions
        .iter()
        .zip(&rest)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, Real::max);
    assert!(worst < 1e-6, "{worst}");
    // Bad input is refused, naming the vertex.
    let e = m
        .set_constraints(&Constraints::fixed(vec![1_000_000]))
        .unwrap_err();
    assert!(e.to_string().contains("1000000"));
    assert!(m.step(-1.0).is_err());
}

#[test]
fn a_model_from_an_image_draws_a_closed_marching_surface() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images/");
    let img = crate::image::read_image(format!("{dir}anatomical.nii"), 1.0).unwrap();
    let (lo, hi) = img.min_max().unwrap();
    let grid = crate::voxel::from_image_threshold(&img, lo + 0.3 * (hi - lo), hi, 2).unwrap();
    let mut m = ChainMail::new(
        grid,
        None,
        Material::new(3000.0, 0.3).unwrap(),
        ChainMailParams::default(),
    )
    .unwrap();
    let s = m.surface();
    let ef = crate::mesh::topology::edge_faces(s.triangles);
    assert_eq!(ef.border_edges().count(), 0);
    assert!(crate::mesh::surface::signed_volume_of(s.positions, s.triangles) > 0.0);
    // Every marching vertex is the midpoint of an occupied-empty lattice edge (at most a
    // body diagonal, √3 h long), so the depth map puts it within (√3 − 1/2) h of zero.
    let h = m.lattice().spacing.max_element();
    let worst = s
        .positions
        .iter()
        .map(|p| m.rest_depth(*p).abs())
        .fold(0.0, Real::max);
    assert!(worst <= 1.24 * h);
    let top = (0..s.positions.len())
        .max_by(|&a, &b| s.positions[a].z.total_cmp(&s.positions[b].z))
        .unwrap();
    let target = s.positions[top] - Vec3::Z * h;
    m.set_constraints(&Constraints {
        fixed: vec![],
        prescribed: vec![Prescribed {
            vertex: top as u32,
            position: target,
        }],
    })
    .unwrap();
    m.step(0.01).unwrap();
    assert!(m.surface().positions[top].distance(target) < 1e-9 * h.max(1.0));
    assert!(m.lattice().violated_links(1e-12).is_empty());
}
