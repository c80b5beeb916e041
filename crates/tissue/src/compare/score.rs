//! The scoring rules: each criterion's measurements become a share in [0, 1] by a
//! documented rule, times the criterion's weight. A measurement that failed scores 0 for its
//! part, and the cell says why. `docs/compare.md` states every rule in words.

use crate::math::Real;

use super::Reference;
use super::record::{Cell, KindRecord, KindScores, Measure};
use super::setup::Scenario;
use super::survey::{CRITERIA, survey_column};

/// 1 at `x <= good`, 0 at `x >= bad`, linear between.
pub fn lin(x: Real, good: Real, bad: Real) -> Real {
    ((bad - x) / (bad - good)).clamp(0.0, 1.0)
}

/// `lin` on log10 scales (`good` and `bad` > 0; either order).
pub fn logs(x: Real, good: Real, bad: Real) -> Real {
    if x.is_nan() || x <= 0.0 {
        return if good < bad { 1.0 } else { 0.0 };
    }
    lin(x.log10(), good.log10(), bad.log10())
}

fn val(r: &KindRecord, k: &str) -> Option<Real> {
    r.measures.get(k).and_then(|m| m.value)
}

fn why(r: &KindRecord, k: &str) -> String {
    match r.measures.get(k) {
        Some(Measure {
            value: None,
            note: Some(n),
            ..
        }) => n.clone(),
        Some(_) => String::new(),
        None => format!("{k} not measured"),
    }
}

/// A value for the table, or the reason it is missing.
fn show(r: &KindRecord, k: &str, fmt: impl Fn(Real) -> String) -> String {
    match val(r, k) {
        Some(v) => fmt(v),
        None => format!("✗ {}", why(r, k)),
    }
}

fn e2(v: Real) -> String {
    format!("{v:.2e}")
}
fn pct(v: Real) -> String {
    format!("{:.1} %", 100.0 * v)
}

/// Scores one kind.
pub fn score_kind(r: &KindRecord, sc: &Scenario, reference: &Reference) -> KindScores {
    let survey = survey_column(&r.kind);
    let mut cells = Vec::with_capacity(CRITERIA.len());
    for (i, c) in CRITERIA.iter().enumerate() {
        let (share, shown) = match &r.build_error {
            Some(e) => (0.0, format!("✗ build failed: {e}")),
            None => rule(c.key, r, sc, reference),
        };
        cells.push(Cell {
            criterion: c.key.into(),
            score: (share.clamp(0.0, 1.0) * c.weight * 100.0).round() / 100.0,
            shown,
            survey: survey.map(|s| s.scores[i]),
        });
    }
    let mut groups = [0.0; 3];
    let mut survey_groups = [0.0; 3];
    for (cell, c) in cells.iter().zip(&CRITERIA) {
        groups[c.group] += cell.score;
        survey_groups[c.group] += cell.survey.unwrap_or(0.0);
    }
    KindScores {
        kind: r.kind.clone(),
        total: groups.iter().sum(),
        groups,
        survey_groups: survey.map(|_| survey_groups),
        survey_total: survey.map(|s| s.scores.iter().sum()),
        cells,
    }
}

/// The share (0..1) and the text shown for criterion `key`.
fn rule(key: &str, r: &KindRecord, sc: &Scenario, rf: &Reference) -> (Real, String) {
    let v = |k: &str| val(r, k);
    match key {
        // Real-time factor (wall s per simulated s) at the haptic and the visual step:
        // full at <= 1, nothing at >= 100 (log scale); half the weight each.
        "velocity" => {
            let part = |k: &str| v(k).map_or(0.0, |c| 0.5 * logs(c * 1e3, 1.0, 100.0));
            (
                part("cost_haptic") + part("cost_visual"),
                format!(
                    "1 ms: {} · 1/60 s: {} (s per sim. ms) · contact update {}",
                    show(r, "cost_haptic", e2),
                    show(r, "cost_visual", e2),
                    show(r, "contact_latency", |x| format!("{:.3} ms", 1e3 * x))
                ),
            )
        }
        // 0.4 stable step (full at >= 1/60 s, nothing at <= 1e-5 s, log), 0.4 share of random
        // paths that finish finite, 0.2 the inverted element handled.
        "robustness" => {
            let dt = v("stable_dt").map_or(0.0, |d| logs(d, 1.0 / 60.0, 1e-5));
            let rnd = v("random_success").unwrap_or(0.0);
            let inv = v("inverted_element").unwrap_or(0.0);
            (
                0.4 * dt + 0.4 * rnd + 0.2 * inv,
                format!(
                    "stable dt {} · random paths {} · inverted element: {}",
                    show(r, "stable_dt", |x| format!("{x:.2e} s")),
                    show(r, "random_success", pct),
                    r.measures
                        .get("inverted_element")
                        .and_then(|m| m.note.clone())
                        .unwrap_or_default()
                ),
            )
        }
        // Half build time (full at <= 10 ms, nothing at >= 10 s, log), half memory (full at
        // <= 1 MB, nothing at >= 1 GB, log).
        "precomputations" => {
            let t = v("build_seconds").map_or(0.0, |x| logs(x, 0.01, 10.0));
            let m = v("memory_bytes").map_or(0.0, |x| logs(x, 1e6, 1e9));
            (
                0.5 * t + 0.5 * m,
                format!(
                    "build {} · memory {}",
                    show(r, "build_seconds", |x| format!("{x:.3} s")),
                    show(r, "memory_bytes", |x| format!("{:.2} MB", x / 1e6))
                ),
            )
        }
        // Unknowns per organ surface dof (3 per surface vertex): full at <= 1, nothing at >= 30.
        "dimension" => {
            let unit = 3.0 * sc.surface_vertices.max(1) as Real;
            (
                v("dofs").map_or(0.0, |d| logs(d / unit, 1.0, 30.0)),
                show(r, "dofs", |d| {
                    format!("{d:.0} unknowns ({:.2}× surface dofs)", d / unit)
                }),
            )
        }
        // Cannot cut: 0. Can: 0.5, + 0.2 surface closed and oriented after five cuts, + 0.2
        // still stable after them, + 0.1 cut cost (full at <= 1 ms, nothing at >= 1 s, log).
        "flexibility" => match v("can_cut") {
            Some(c) if c > 0.0 => {
                let closed = v("cut_closed").unwrap_or(0.0);
                let stable = v("cut_stable").unwrap_or(0.0);
                let cost = v("cut_seconds").map_or(0.0, |x| logs(x, 1e-3, 1.0));
                (
                    0.5 + 0.2 * closed + 0.2 * stable + 0.1 * cost,
                    format!(
                        "cuts · {} per cut · closed {} · stable after {}",
                        show(r, "cut_seconds", |x| format!("{:.2} ms", 1e3 * x)),
                        if closed > 0.0 { "yes" } else { "no" },
                        if stable > 0.0 { "yes" } else { "no" }
                    ),
                )
            }
            _ => (
                0.0,
                format!(
                    "✗ {}",
                    r.measures
                        .get("can_cut")
                        .and_then(|m| m.note.clone())
                        .unwrap_or_else(|| "cannot cut".into())
                ),
            ),
        },
        // 0.6 when the drawn surface is made of mechanical nodes (no mapping), + 0.4 per-frame
        // cost of the surface to draw (full at <= 1 % of a 60 Hz frame, nothing at >= 100 %).
        "rendering" => {
            let direct = v("surface_is_mechanical").unwrap_or(0.0);
            let cost = v("render_seconds").map_or(0.0, |x| logs(x, 1.0 / 6000.0, 1.0 / 60.0));
            (
                0.6 * direct + 0.4 * cost,
                format!(
                    "{} · {} per frame",
                    if direct > 0.0 {
                        "mechanical surface drawn"
                    } else {
                        "mapped surface"
                    },
                    show(r, "render_seconds", |x| format!("{:.3} ms", 1e3 * x))
                ),
            )
        }
        // The elements needed to bring the probe force within 5 % of the reference (full at
        // <= 1000, nothing at >= 100 000, log), from the mesh-size ladder. Without it (a
        // single size, `--quick`), the survey's other form: half the element count, half the
        // force error reached with them (full at 0, nothing at >= 50 %).
        "mesh_dimension" => match v("elements_for_5pct") {
            Some(n5) => (
                logs(n5.max(1.0), 1e3, 1e5),
                format!(
                    "{} elements for 5 % · {} elements used",
                    show(r, "elements_for_5pct", |x| format!("{x:.0}")),
                    show(r, "elements", |x| format!("{x:.0}"))
                ),
            ),
            None => {
                let n = v("elements").map_or(0.0, |x| logs(x.max(1.0), 1e3, 1e5));
                let e = v("force_error").map_or(0.0, |x| lin(x, 0.0, 0.5));
                (
                    0.5 * n + 0.5 * e,
                    format!(
                        "{} elements · force error {}",
                        show(r, "elements", |x| format!("{x:.0}")),
                        show(r, "force_error", pct)
                    ),
                )
            }
        },
        // Half the input it needs (surface: full, tetrahedra: a quarter), half the time from
        // the file to a runnable model (full at <= 10 ms, nothing at >= 10 s, log).
        "mesh_acquisition" => {
            let tets = v("needs_tetrahedra").unwrap_or(1.0);
            let t = v("acquisition_seconds").map_or(0.0, |x| logs(x, 0.01, 10.0));
            (
                0.5 * if tets > 0.0 { 0.25 } else { 1.0 } + 0.5 * t,
                format!(
                    "{} · {}",
                    if tets > 0.0 { "tetrahedra" } else { "surface" },
                    show(r, "acquisition_seconds", |x| format!("{x:.3} s"))
                ),
            )
        }
        // Half probe force error, half surface displacement error (RMS, relative), against
        // the reference at the shallow indentation: full at 0, nothing at >= 100 %.
        "deformation" => {
            let f = v("force_error").map_or(0.0, |x| lin(x, 0.0, 1.0));
            let d = v("displacement_error").map_or(0.0, |x| lin(x, 0.0, 1.0));
            (
                0.5 * f + 0.5 * d,
                format!(
                    "force {} (error {}) · displacement error {}{}{}",
                    show(r, "force_shallow", |x| format!("{x:.4} N")),
                    show(r, "force_error", pct),
                    show(r, "displacement_error", pct),
                    // A run still moving at the time limit, and how the probe held the
                    // organ (exact fine points, per-vertex planes, or nothing).
                    match r
                        .measures
                        .get("force_error")
                        .and_then(|m| m.note.as_deref())
                    {
                        Some(n) if val(r, "force_error").is_some() => format!(" ({n})"),
                        _ => String::new(),
                    },
                    match r.measures.get("contacts_shallow") {
                        Some(Measure { note: Some(n), .. }) => format!(" · probe held by {n}"),
                        _ => String::new(),
                    }
                ),
            )
        }
        // |ΔV/V - ΔV/V of the reference| under the plate at ν = 0.45: full at 0, nothing at
        // >= 5 % of the volume.
        "volume" => (
            v("compression_volume_error").map_or(0.0, |x| lin(x, 0.0, 0.05)),
            format!(
                "ΔV {} (reference {:.2} %)",
                show(r, "compression_volume", pct),
                100.0 * rf.compression_volume
            ),
        ),
        // 0.5 spurious reaction under the 90° rotation of the support (in units of the
        // reference probe force: full at 0, nothing at >= 1), 0.3 its volume change (full at
        // 0, nothing at >= 10 %), 0.2 the deep (20 %) indentation force error (nothing >= 100 %).
        "great_deformations" => {
            let f = v("rotation_force").map_or(0.0, |x| lin(x, 0.0, 1.0));
            let dv = v("rotation_volume").map_or(0.0, |x| lin(x.abs(), 0.0, 0.1));
            let d = v("deep_error").map_or(0.0, |x| lin(x, 0.0, 1.0));
            (
                0.5 * f + 0.3 * dv + 0.2 * d,
                format!(
                    "rotation: force {} ×F_ref, ΔV {} · deep force error {}",
                    show(r, "rotation_force", |x| format!("{x:.3}")),
                    show(r, "rotation_volume", pct),
                    show(r, "deep_error", pct)
                ),
            )
        }
        // Static models: 0 (no inertia). Dynamic: 0.6 first frequency against the reference
        // (full at equal, nothing at >= 100 % off), 0.4 far-side delay likewise.
        "dynamics" => {
            if v("is_static").unwrap_or(0.0) > 0.0 {
                return (0.0, "static: no dynamics".into());
            }
            let f = match (v("frequency"), rf.frequency) {
                (Some(f), Some(fr)) => lin((f / fr - 1.0).abs(), 0.0, 1.0),
                _ => 0.0,
            };
            let d = match (v("delay"), rf.delay) {
                (Some(d), Some(dr)) => lin((d / dr - 1.0).abs(), 0.0, 1.0),
                _ => 0.0,
            };
            (
                0.6 * f + 0.4 * d,
                format!(
                    "f₁ {} (reference {}) · delay {}",
                    show(r, "frequency", |x| format!("{x:.2} Hz")),
                    rf.frequency.map_or("—".into(), |x| format!("{x:.2} Hz")),
                    show(r, "delay", |x| format!("{:.1} ms", 1e3 * x))
                ),
            )
        }
        // Half effective E (full at the input, nothing at >= 50 % off), half effective ν
        // against the reference's on the same bar (nothing at >= 0.25 off).
        "parameters" => {
            let e = v("effective_E").map_or(0.0, |x| lin((x - 1.0).abs(), 0.0, 0.5));
            let n = v("effective_nu").map_or(0.0, |x| lin((x - rf.bar_nu).abs(), 0.0, 0.25));
            (
                0.5 * e + 0.5 * n,
                format!(
                    "E_eff {} · ν_eff {} (reference {:.3})",
                    show(r, "effective_E", |x| format!("{x:.2}× E")),
                    show(r, "effective_nu", |x| format!("{x:.3}")),
                    rf.bar_nu
                ),
            )
        }
        _ => (0.0, "unknown criterion".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_are_monotone_and_bounded() {
        assert_eq!(lin(0.0, 0.0, 1.0), 1.0);
        assert_eq!(lin(2.0, 0.0, 1.0), 0.0);
        assert!((logs(10.0, 1.0, 100.0) - 0.5).abs() < 1e-12);
        assert!((logs(1e-3, 1.0 / 60.0, 1e-5) - logs(1e-3, 1.0 / 60.0, 1e-5)).abs() < 1e-12);
        assert_eq!(logs(1.0, 1.0 / 60.0, 1e-5), 1.0);
        assert_eq!(logs(1e-6, 1.0 / 60.0, 1e-5), 0.0);
    }
}
