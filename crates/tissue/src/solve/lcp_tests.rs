use super::*;
use faer::linalg::solvers::Solve;

/// A deterministic generator (xorshift) for the tests' random problems.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> Real {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as Real / (1u64 << 53) as Real * 2.0 - 1.0
    }
}

/// M = Gᵀ G for a `rank` × `n` random G: positive semi-definite, singular below full rank.
fn random_psd(rng: &mut Rng, n: usize, rank: usize) -> Mat<Real> {
    let g = Mat::<Real>::from_fn(rank, n, |_, _| rng.next());
    g.transpose() * &g
}

fn check_complementary(m: &Mat<Real>, b: &[Real], bilateral: usize, l: &[Real]) {
    let n = b.len();
    let scale = b.iter().fold(1e-300, |a: Real, v| a.max(v.abs()));
    for i in 0..n {
        let w: Real = b[i] + (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>();
        if i < bilateral {
            assert!(w.abs() < 1e-7 * scale, "held row {i}: gap {w}");
        } else {
            assert!(l[i] >= 0.0, "row {i} pulls: {}", l[i]);
            assert!(w > -1e-7 * scale, "row {i} penetrates: {w}");
            assert!(
                l[i] * w.abs() < 1e-7 * scale * (1.0 + l[i]),
                "row {i}: λ {} w {w}",
                l[i]
            );
        }
    }
}

#[test]
fn random_definite_and_singular_problems_are_complementary() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    for trial in 0..300usize {
        let n: usize = 1 + trial % 23;
        // Every third problem singular: more rows than directions.
        let rank = if trial % 3 == 0 { n.div_ceil(2) } else { n + 2 };
        let m = random_psd(&mut rng, n, rank);
        let bilateral = if trial % 5 == 0 && rank >= n {
            n / 3
        } else {
            0
        };
        // A problem that has a solution, as contact problems do (a singular M with an
        // arbitrary b may have none): b = w* − M λ* for a complementary pair.
        let (mut l, mut w) = (vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            if i < bilateral || rng.next() > 0.0 {
                l[i] = rng.next() + if i < bilateral { 0.0 } else { 1.0 };
            } else {
                w[i] = rng.next() + 1.0;
            }
        }
        let b: Vec<Real> = (0..n)
            .map(|i| w[i] - (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>())
            .collect();
        let s = solve_mixed(m.as_ref(), &b, bilateral, &[]).unwrap();
        check_complementary(&m, &b, bilateral, &s.lambda);
    }
}

#[test]
fn a_singular_problem_gives_the_displacement_of_the_exact_solution() {
    // Two points on one spring: both rows say "push the one unknown to 1". The pushes
    // split between them but their sum is what one row alone needs.
    let m = Mat::<Real>::from_fn(2, 2, |_, _| 0.5);
    let b = [-1.0, -1.0];
    let s = solve_mixed(m.as_ref(), &b, 0, &[]).unwrap();
    let sum = s.lambda[0] + s.lambda[1];
    assert!((sum - 2.0).abs() < 1e-6, "{:?}", s.lambda);
    // A point that is already clear of the plane is not pushed.
    let m = Mat::<Real>::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 0.2 });
    let s = solve_mixed(m.as_ref(), &[-1.0, 3.0], 0, &[]).unwrap();
    assert_eq!(s.lambda[1], 0.0);
    assert!((s.lambda[0] - 1.0).abs() < 1e-8);
}

#[test]
fn bad_sizes_and_values_are_errors() {
    let m = Mat::<Real>::identity(2, 2);
    assert!(solve_mixed(m.as_ref(), &[1.0], 0, &[]).is_err());
    assert!(solve_mixed(m.as_ref(), &[Real::NAN, 1.0], 0, &[]).is_err());
    let zero = Mat::<Real>::zeros(1, 1);
    assert!(solve_mixed(zero.as_ref(), &[1.0], 1, &[]).is_err());
}

/// The solver this module had before (block principal pivoting on M with its unilateral
/// diagonal raised by `REGULARISATION`, Murty's one-row rule as the fallback), kept as the
/// second implementation the tests compare with. `None` when it reaches its cap.
fn pivoting(m: &Mat<Real>, b: &[Real], bilateral: usize) -> Option<(Vec<Real>, usize)> {
    let n = b.len();
    let max_diag = (0..n).map(|i| m[(i, i)].abs()).fold(0.0, Real::max);
    let eps = REGULARISATION * max_diag.max(Real::MIN_POSITIVE);
    let a = |i: usize, j: usize| m[(i, j)] + if i == j && i >= bilateral { eps } else { 0.0 };
    let mut active: Vec<bool> = (0..n).map(|i| i < bilateral || b[i] < 0.0).collect();
    let (mut best, mut tries) = (usize::MAX, 3);
    for round in 1..=10 * n + 50 {
        let rows: Vec<usize> = (0..n).filter(|&i| active[i]).collect();
        let mut lambda = vec![0.0; n];
        if !rows.is_empty() {
            let k = rows.len();
            let mat = Mat::<Real>::from_fn(k, k, |r, c| a(rows[r], rows[c]));
            let mut x = Mat::<Real>::from_fn(k, 1, |r, _| -b[rows[r]]);
            mat.llt(faer::Side::Lower).ok()?.solve_in_place(x.as_mut());
            for (r, &i) in rows.iter().enumerate() {
                lambda[i] = x[(r, 0)];
            }
        }
        let w: Vec<Real> = (0..n)
            .map(|i| b[i] + (0..n).map(|j| a(i, j) * lambda[j]).sum::<Real>())
            .collect();
        let scale_w = b.iter().fold(Real::MIN_POSITIVE, |s, v| s.max(v.abs()));
        let scale_l = lambda
            .iter()
            .fold(Real::MIN_POSITIVE, |s, v| s.max(v.abs()));
        let wrong: Vec<usize> = (bilateral..n)
            .filter(|&i| {
                if active[i] {
                    lambda[i] < -1e-12 * scale_l
                } else {
                    w[i] < -1e-12 * scale_w
                }
            })
            .collect();
        if wrong.is_empty() {
            return Some((lambda, round));
        }
        if wrong.len() < best {
            (best, tries) = (wrong.len(), 3);
            wrong.iter().for_each(|&i| active[i] = !active[i]);
        } else if tries > 0 {
            tries -= 1;
            wrong.iter().for_each(|&i| active[i] = !active[i]);
        } else if let Some(&i) = wrong.last() {
            active[i] = !active[i];
        }
    }
    None
}

/// The unique solution of a definite problem by trying every set of pushing rows.
fn brute_force(m: &Mat<Real>, b: &[Real], bilateral: usize) -> Vec<Real> {
    let n = b.len();
    let free = n - bilateral;
    for set in 0..1usize << free {
        let rows: Vec<usize> = (0..n)
            .filter(|&i| i < bilateral || set >> (i - bilateral) & 1 == 1)
            .collect();
        let mut lambda = vec![0.0; n];
        if !rows.is_empty() {
            let k = rows.len();
            let mat = Mat::<Real>::from_fn(k, k, |r, c| m[(rows[r], rows[c])]);
            let x = mat
                .partial_piv_lu()
                .solve(Mat::<Real>::from_fn(k, 1, |r, _| -b[rows[r]]));
            for (r, &i) in rows.iter().enumerate() {
                lambda[i] = x[(r, 0)];
            }
        }
        let ok = (bilateral..n).all(|i| {
            let w = b[i] + (0..n).map(|j| m[(i, j)] * lambda[j]).sum::<Real>();
            lambda[i] >= -1e-10 && w >= -1e-10
        });
        if ok {
            return lambda;
        }
    }
    panic!("a definite problem has a solution");
}

#[test]
fn small_definite_problems_agree_with_every_pushing_set_tried() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for trial in 0..200usize {
        let n = 1 + trial % 10;
        let m = random_psd(&mut rng, n, n + 2);
        let bilateral = if trial % 4 == 0 { n / 3 } else { 0 };
        let b: Vec<Real> = (0..n).map(|_| rng.next()).collect();
        let s = solve_mixed(m.as_ref(), &b, bilateral, &[]).unwrap();
        let exact = brute_force(&m, &b, bilateral);
        for (i, (l, e)) in s.lambda.iter().zip(&exact).enumerate() {
            assert!(
                (l - e).abs() < 1e-8 * (1.0 + e.abs()),
                "trial {trial} row {i}: {l} {e}"
            );
        }
        // The old pivoting solver answers the regularised problem: the same to ~1e-9.
        let (old, _) = pivoting(&m, &b, bilateral).unwrap();
        for (l, o) in s.lambda.iter().zip(&old) {
            assert!(
                (l - o).abs() < 1e-6 * (1.0 + o.abs()),
                "trial {trial}: {l} {o}"
            );
        }
    }
}

/// Barycentric weights of the vertices of a triangle cut flat `level` times (each edge in
/// 2^level): (2^level + 1)(2^level + 2)/2 points, the corners among them.
fn fine_weights(level: u32) -> Vec<[Real; 3]> {
    let s = 1usize << level;
    let mut out = Vec::new();
    for i in 0..=s {
        for j in 0..=s - i {
            let (a, c) = (i as Real / s as Real, j as Real / s as Real);
            out.push([1.0 - a - c, a, c]);
        }
    }
    out
}

/// A row: its (coarse vertex, weight) terms and its normal.
type PointRow = (Vec<(usize, Real)>, [Real; 3]);

/// M = J C Jᵀ and, for coarse forces, Jᵀ: rows of (vertex, weight) terms along a normal, on
/// a compliance C of 3 dofs per coarse vertex.
fn response(c: &Mat<Real>, rows: &[PointRow]) -> (Mat<Real>, Mat<Real>) {
    let dofs = c.nrows();
    let jt = Mat::<Real>::from_fn(dofs, rows.len(), |d, r| {
        let (terms, normal) = &rows[r];
        terms
            .iter()
            .filter(|t| t.0 == d / 3)
            .map(|t| t.1 * normal[d % 3])
            .sum()
    });
    let cj = c * &jt;
    (jt.transpose() * &cj, jt)
}

/// A random symmetric positive definite compliance of `dofs` unknowns.
fn random_compliance(rng: &mut Rng, dofs: usize) -> Mat<Real> {
    let g = Mat::<Real>::from_fn(dofs, dofs, |_, _| rng.next());
    let mut c = g.transpose() * &g * (1.0 / dofs as Real);
    for d in 0..dofs {
        c[(d, d)] += 0.5;
    }
    c
}

/// Coarse forces Jᵀ λ.
fn coarse(jt: &Mat<Real>, lambda: &[Real]) -> Vec<Real> {
    (0..jt.nrows())
        .map(|d| (0..jt.ncols()).map(|r| jt[(d, r)] * lambda[r]).sum())
        .collect()
}

#[test]
fn points_on_one_triangle_under_a_plane_push_as_its_vertices() {
    // 561 points of one coarse triangle (cut 5 times), all to rise 1 mm along z: a rank-3
    // response. The corners are among them, so the points ask exactly what the three
    // vertices alone ask: the same displacement and the same coarse forces.
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let c = random_compliance(&mut rng, 9);
    let z = [0.0, 0.0, 1.0];
    let fine: Vec<_> = fine_weights(5)
        .into_iter()
        .map(|w| ((0..3).zip(w).collect::<Vec<_>>(), z))
        .collect();
    let corners: Vec<_> = (0..3).map(|v| (vec![(v, 1.0)], z)).collect();
    let (mf, jf) = response(&c, &fine);
    let (mc, jc) = response(&c, &corners);
    let h = 1e-3;
    let bf = vec![-h; fine.len()];
    let coarse_answer = solve_mixed(mc.as_ref(), &[-h; 3], 0, &[]).unwrap();
    let fc = coarse(&jc, &coarse_answer.lambda);
    // Cold, and from the worst guess (every point pushing).
    for guess in [vec![], vec![true; fine.len()]] {
        let s = solve_mixed(mf.as_ref(), &bf, 0, &guess).unwrap();
        check_complementary(&mf, &bf, 0, &s.lambda);
        let ff = coarse(&jf, &s.lambda);
        for (a, e) in ff.iter().zip(&fc) {
            assert!((a - e).abs() < 1e-9 * fc.iter().fold(0.0, |m: Real, v| m.max(v.abs())));
        }
        let total: Real = s.lambda.iter().sum();
        let expected: Real = coarse_answer.lambda.iter().sum();
        assert!(
            (total - expected).abs() < 1e-10 * expected,
            "{total} {expected}"
        );
        // A basic answer: no more pushing points than independent directions.
        assert!(s.lambda.iter().filter(|&&l| l > 0.0).count() <= 3);
    }
}

/// A coarse patch (a `side` × `side` grid of vertices, 1 cm apart, two triangles per cell)
/// cut flat `level` times, pressed by a sphere of radius 2.5 cm to `depth`: each point
/// one row along the sphere's normal through it (duplicated on shared edges, as exactly
/// dependent rows). The problems the old solver did not finish.
fn sphere_on_patch(
    rng: &mut Rng,
    side: usize,
    level: u32,
    depth: Real,
) -> (Mat<Real>, Vec<Real>, Mat<Real>) {
    let c = random_compliance(rng, 3 * side * side);
    let pos = |v: usize| [(v % side) as Real * 0.01, (v / side) as Real * 0.01, 0.0];
    let mid = 0.005 * (side - 1) as Real;
    let radius = 0.025;
    let centre = [mid, mid, radius - depth];
    let mut rows = Vec::new();
    let mut b = Vec::new();
    for cy in 0..side - 1 {
        for cx in 0..side - 1 {
            let v = cy * side + cx;
            for tri in [[v, v + 1, v + side + 1], [v, v + side + 1, v + side]] {
                for w in fine_weights(level) {
                    let p: Vec<Real> = (0..3)
                        .map(|a| (0..3).map(|k| w[k] * pos(tri[k])[a]).sum())
                        .collect();
                    let d: Vec<Real> = (0..3).map(|a| p[a] - centre[a]).collect();
                    let dist = d.iter().map(|x| x * x).sum::<Real>().sqrt();
                    if dist > radius + 0.004 {
                        continue;
                    }
                    let normal = [-d[0] / dist, -d[1] / dist, -d[2] / dist];
                    // The gap along the normal pushing the point out of the sphere.
                    b.push(dist - radius);
                    rows.push((tri.iter().copied().zip(w).collect::<Vec<_>>(), normal));
                }
            }
        }
    }
    let (m, jt) = response(&c, &rows);
    (m, b, jt)
}

#[test]
fn a_sphere_on_a_finely_cut_patch_is_complementary_and_its_displacement_unique() {
    // 1,000+ rows over 25 coarse vertices (75 directions): the order of the rows changes
    // which points push, not the coarse forces (the displacement is unique).
    let mut rng = Rng(0x0bad_cafe_f00d_d00d);
    let (m, b, jt) = sphere_on_patch(&mut rng, 5, 3, 0.004);
    let n = b.len();
    assert!(n > 1000, "{n} rows");
    let s = solve_mixed(m.as_ref(), &b, 0, &[]).unwrap();
    check_complementary(&m, &b, 0, &s.lambda);
    let f = coarse(&jt, &s.lambda);
    let order: Vec<usize> = (0..n).rev().collect();
    let mr = Mat::<Real>::from_fn(n, n, |i, j| m[(order[i], order[j])]);
    let br: Vec<Real> = order.iter().map(|&i| b[i]).collect();
    let sr = solve_mixed(mr.as_ref(), &br, 0, &[]).unwrap();
    let mut back = vec![0.0; n];
    for (r, &i) in order.iter().enumerate() {
        back[i] = sr.lambda[r];
    }
    let fr = coarse(&jt, &back);
    let scale = f.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
    assert!(scale > 0.0);
    for (x, y) in f.iter().zip(&fr) {
        assert!((x - y).abs() < 1e-8 * scale, "{x} {y}");
    }
    let pushing = s.lambda.iter().filter(|&&l| l > 0.0).count();
    assert!(pushing <= 75, "{pushing} pushing");
}

#[test]
fn held_rows_beside_dependent_points_are_held_exactly() {
    // Two of the points held exactly (bilateral rows, one of them 1 mm past its plane),
    // every point also a unilateral row: the held points' own unilateral copies are
    // exactly dependent on the held rows.
    let mut rng = Rng(0x5555_aaaa_3333_cccc);
    let (m, b, _) = sphere_on_patch(&mut rng, 4, 2, 0.003);
    let pts = b.len();
    let mut order: Vec<usize> = (0..pts).collect();
    order.sort_by(|&i, &j| b[i].total_cmp(&b[j]));
    let held = [order[0], order[pts / 2]];
    let rows: Vec<usize> = held.iter().copied().chain(0..pts).collect();
    let n = rows.len();
    let mh = Mat::<Real>::from_fn(n, n, |i, j| m[(rows[i], rows[j])]);
    let mut bh: Vec<Real> = rows.iter().map(|&i| b[i]).collect();
    bh[1] -= 0.001; // the second held point 1 mm further than its plane
    let s = solve_mixed(mh.as_ref(), &bh, 2, &[]).unwrap();
    check_complementary(&mh, &bh, 2, &s.lambda);
    // A held point's unilateral copy asked to go 1 mm further than its hold: no push can
    // move it (it moves only with the held row), an error rather than a huge push.
    let mut bad = bh.clone();
    bad[2 + held[0]] = bh[0] - 1e-3;
    assert!(solve_mixed(mh.as_ref(), &bad, 2, &[]).is_err());
}

#[test]
fn a_penetrating_row_with_no_response_is_an_error() {
    let m = Mat::<Real>::from_fn(2, 2, |i, j| if i == 0 && j == 0 { 1.0 } else { 0.0 });
    let e = solve_mixed(m.as_ref(), &[-1.0, -1.0], 0, &[]).unwrap_err();
    assert!(e.to_string().contains("row 1"), "{e}");
    // Clear of its plane it is simply free.
    let s = solve_mixed(m.as_ref(), &[-1.0, 1.0], 0, &[]).unwrap();
    assert_eq!(s.lambda, vec![1.0, 0.0]);
}

/// Rows, rounds and time of both solvers on the sphere-on-patch problems cut 1–4 times (the
/// old one not run on level 4).
/// `cargo test --release -p tissue --lib solve::lcp::tests::cost_study -- --ignored --nocapture`
#[test]
#[ignore = "study: prints both solvers' rows, rounds and time"]
fn cost_study() {
    for level in 1..=4 {
        let mut rng = Rng(0x0bad_cafe_f00d_d00d);
        let (m, b, jt) = sphere_on_patch(&mut rng, 5, level, 0.004);
        // Timed on a second run (the first pays for the allocations' first touch).
        let _ = solve_mixed(m.as_ref(), &b, 0, &[]);
        let t = std::time::Instant::now();
        let s = solve_mixed(m.as_ref(), &b, 0, &[]);
        let new_ms = t.elapsed().as_secs_f64() * 1e3;
        // The old solver takes minutes to reach its cap on level 4's 3,000+ rows.
        let t = std::time::Instant::now();
        let old = if level <= 3 {
            pivoting(&m, &b, 0)
        } else {
            None
        };
        let old_ms = t.elapsed().as_secs_f64() * 1e3;
        let (rounds, force) = match &s {
            Ok(s) => (s.rounds, coarse(&jt, &s.lambda).iter().sum::<Real>()),
            Err(_) => (0, Real::NAN),
        };
        let (old_rounds, old_force) = match &old {
            Some((l, r)) => (format!("{r}"), coarse(&jt, l).iter().sum::<Real>()),
            None if level > 3 => ("not run".into(), Real::NAN),
            None => (format!("capped at {}", 10 * b.len() + 50), Real::NAN),
        };
        println!(
            "level {level}: {} rows | new {rounds} rounds {new_ms:.1} ms, Σ coarse force \
             {force:.9e} | old {old_rounds} rounds {old_ms:.1} ms, {old_force:.9e}",
            b.len()
        );
    }
}
