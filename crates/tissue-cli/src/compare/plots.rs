//! The plots, SVG and PNG (plotters; text from the vendored DejaVu Sans): the radar of the
//! group totals (Fig. 7, measured), the radar per criterion, probe force against
//! indentation beside the reference, volume change under compression, cost against mesh
//! size, and error against cost (the Pareto front).

use std::path::Path;

use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use tissue::compare::CompareRecord;
use tissue::compare::survey::{CRITERIA, GROUPS};

const FONT: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

fn colour(i: usize) -> RGBColor {
    const C: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    let c = C[i % C.len()];
    if i >= C.len() {
        RGBColor(c.0 / 2, c.1 / 2, c.2 / 2)
    } else {
        c
    }
}

type Err = Box<dyn std::error::Error>;

pub fn all(r: &CompareRecord, out: &Path) -> anyhow::Result<()> {
    register_font();
    macro_rules! draw {
        ($name:expr, $size:expr, $f:ident) => {{
            let svg = out.join(format!("{}.svg", $name));
            let png = out.join(format!("{}.png", $name));
            {
                let a = SVGBackend::new(&svg, $size).into_drawing_area();
                $f(r, &a).map_err(|e| anyhow!("{}.svg: {e}", $name))?;
                a.present().map_err(|e| anyhow!("{}.svg: {e}", $name))?;
            }
            {
                let a = BitMapBackend::new(&png, $size).into_drawing_area();
                $f(r, &a).map_err(|e| anyhow!("{}.png: {e}", $name))?;
                a.present().map_err(|e| anyhow!("{}.png: {e}", $name))?;
            }
        }};
    }
    draw!("radar", (900, 700), radar_groups);
    draw!("radar-criteria", (1000, 800), radar_criteria);
    draw!("force-indentation", (900, 600), force_indentation);
    draw!("volume-compression", (900, 600), volume_compression);
    draw!("cost-size", (900, 600), cost_size);
    draw!("mesh-convergence", (900, 600), mesh_convergence);
    draw!("pareto", (900, 600), pareto);
    Ok(())
}

/// A radar: one axis per label, values over `max` per axis, one polygon per series.
fn radar<DB: DrawingBackend>(
    a: &DrawingArea<DB, Shift>,
    title: &str,
    labels: &[String],
    max: &[f64],
    series: &[(String, Vec<f64>)],
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    a.fill(&WHITE)?;
    let (w, h) = a.dim_in_pixel();
    let (plot, legend) = a.split_horizontally((w as f64 * 0.68) as u32);
    plot.draw(&Text::new(
        title.to_string(),
        (10, 10),
        ("sans-serif", 18).into_font(),
    ))?;
    let (pw, _) = plot.dim_in_pixel();
    let cx = pw as f64 / 2.0;
    let cy = h as f64 / 2.0 + 10.0;
    let rad = (pw.min(h) as f64) * 0.36;
    let n = labels.len();
    let at = |i: usize, f: f64| {
        let ang = -std::f64::consts::FRAC_PI_2 + 2.0 * std::f64::consts::PI * i as f64 / n as f64;
        (
            (cx + rad * f * ang.cos()) as i32,
            (cy + rad * f * ang.sin()) as i32,
        )
    };
    for ring in [0.25, 0.5, 0.75, 1.0] {
        let mut pts: Vec<(i32, i32)> = (0..n).map(|i| at(i, ring)).collect();
        pts.push(pts[0]);
        plot.draw(&PathElement::new(pts, RGBColor(200, 200, 200)))?;
    }
    for (i, l) in labels.iter().enumerate() {
        plot.draw(&PathElement::new(
            vec![at(i, 0.0), at(i, 1.0)],
            RGBColor(200, 200, 200),
        ))?;
        let (x, y) = at(i, 1.12);
        let text = format!("{l} ({})", max[i]);
        let width = 6 * text.chars().count() as i32;
        plot.draw(&Text::new(
            text,
            (x - width / 2, y - 6),
            ("sans-serif", 12).into_font(),
        ))?;
    }
    for (k, (name, vals)) in series.iter().enumerate() {
        let c = colour(k);
        let mut pts: Vec<(i32, i32)> = vals
            .iter()
            .enumerate()
            .map(|(i, v)| at(i, (v / max[i]).clamp(0.0, 1.0)))
            .collect();
        pts.push(pts[0]);
        plot.draw(&PathElement::new(pts, c.stroke_width(2)))?;
        let y = 40 + 20 * k as i32;
        legend.draw(&Rectangle::new([(5, y), (20, y + 10)], c.filled()))?;
        legend.draw(&Text::new(
            name.clone(),
            (26, y - 2),
            ("sans-serif", 13).into_font(),
        ))?;
    }
    Ok(())
}

fn radar_groups<DB: DrawingBackend>(
    r: &CompareRecord,
    a: &DrawingArea<DB, Shift>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let labels: Vec<String> = GROUPS.iter().map(|g| g.to_string()).collect();
    let series: Vec<(String, Vec<f64>)> = r
        .scores
        .iter()
        .map(|s| (format!("{} ({:.1})", s.kind, s.total), s.groups.to_vec()))
        .collect();
    radar(
        a,
        "Fig. 7, measured: group totals",
        &labels,
        &[15.0; 3],
        &series,
    )
}

fn radar_criteria<DB: DrawingBackend>(
    r: &CompareRecord,
    a: &DrawingArea<DB, Shift>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let labels: Vec<String> = CRITERIA.iter().map(|c| c.name.to_string()).collect();
    let max: Vec<f64> = CRITERIA.iter().map(|c| c.weight).collect();
    let series: Vec<(String, Vec<f64>)> = r
        .scores
        .iter()
        .map(|s| (s.kind.clone(), s.cells.iter().map(|c| c.score).collect()))
        .collect();
    radar(
        a,
        "Scores per criterion (fraction of the weight)",
        &labels,
        &max,
        &series,
    )
}

/// Line plot of named curves (x, y) with the reference in black.
fn curves<DB: DrawingBackend>(
    a: &DrawingArea<DB, Shift>,
    title: &str,
    xl: &str,
    yl: &str,
    reference: Option<&[[f64; 2]]>,
    series: &[(String, Vec<[f64; 2]>)],
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    a.fill(&WHITE)?;
    let all = series
        .iter()
        .flat_map(|(_, p)| p.iter())
        .chain(reference.into_iter().flatten())
        .filter(|p| p[0].is_finite() && p[1].is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (0.0f64, 1e-12f64, 0.0f64, 1e-12f64);
    for p in all {
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
    }
    let mut chart = ChartBuilder::on(a)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1 * 1.05, y0 * 1.05..y1 * 1.05)?;
    chart.configure_mesh().x_desc(xl).y_desc(yl).draw()?;
    if let Some(rf) = reference {
        chart
            .draw_series(LineSeries::new(
                rf.iter().map(|p| (p[0], p[1])),
                BLACK.stroke_width(3),
            ))?
            .label("reference")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLACK.stroke_width(3)));
    }
    for (k, (name, pts)) in series.iter().enumerate() {
        let c = colour(k);
        chart
            .draw_series(LineSeries::new(
                pts.iter()
                    .filter(|p| p[1].is_finite())
                    .map(|p| (p[0], p[1])),
                c.stroke_width(2),
            ))?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], c.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 11))
        .draw()?;
    Ok(())
}

fn force_indentation<DB: DrawingBackend>(
    r: &CompareRecord,
    a: &DrawingArea<DB, Shift>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let series: Vec<(String, Vec<[f64; 2]>)> = r
        .kinds
        .iter()
        .filter_map(|k| {
            k.curves.get("indentation").map(|c| {
                (
                    k.kind.clone(),
                    c.points.iter().map(|p| [1e3 * p[0], p[1]]).collect(),
                )
            })
        })
        .collect();
    let rf: Option<Vec<[f64; 2]>> = r
        .reference
        .curves
        .get("indentation")
        .map(|c| c.points.iter().map(|p| [1e3 * p[0], p[1]]).collect());
    curves(
        a,
        "Probe force against indentation",
        "indentation (mm)",
        "force (N)",
        rf.as_deref(),
        &series,
    )
}

fn volume_compression<DB: DrawingBackend>(
    r: &CompareRecord,
    a: &DrawingArea<DB, Shift>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let series: Vec<(String, Vec<[f64; 2]>)> = r
        .kinds
        .iter()
        .filter_map(|k| {
            k.curves.get("compression").map(|c| {
                (
                    k.kind.clone(),
                    c.points
                        .iter()
                        .map(|p| [1e3 * p[0], 100.0 * p[1]])
                        .collect(),
                )
            })
        })
        .collect();
    let rf: Option<Vec<[f64; 2]>> = r.reference.curves.get("compression").map(|c| {
        c.points
            .iter()
            .map(|p| [1e3 * p[0], 100.0 * p[1]])
            .collect()
    });
    curves(
        a,
        "Volume change under compression (ν = 0.45)",
        "plate travel (mm)",
        "ΔV/V (%)",
        rf.as_deref(),
        &series,
    )
}

/// Labelled point series on log-log axes: one colour per series, its points joined (a
/// mesh-size ladder) and labelled at the last; with `front`, the Pareto front of the last
/// points; with `level`, a dashed horizontal line there.
fn scatter<DB: DrawingBackend>(
    a: &DrawingArea<DB, Shift>,
    title: &str,
    xl: &str,
    yl: &str,
    series: &[(String, Vec<(f64, f64)>)],
    front: bool,
    level: Option<f64>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    a.fill(&WHITE)?;
    let good = |p: &&(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
    let series: Vec<(&String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, p)| (n, p.iter().filter(good).copied().collect::<Vec<_>>()))
        .filter(|(_, p)| !p.is_empty())
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in series
        .iter()
        .flat_map(|(_, p)| p)
        .chain(level.map(|l| (f64::NAN, l)).iter().filter(|p| p.1 > 0.0))
    {
        if p.0.is_finite() {
            x0 = x0.min(p.0);
            x1 = x1.max(p.0);
        }
        y0 = y0.min(p.1);
        y1 = y1.max(p.1);
    }
    if series.is_empty() {
        (x0, x1, y0, y1) = (1e-6, 1.0, 1e-6, 1.0);
    }
    let mut chart = ChartBuilder::on(a)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (x0 / 2.0..x1 * 2.0).log_scale(),
            (y0 / 2.0..y1 * 2.0).log_scale(),
        )?;
    // Log axes put ticks at values like 0.30000000000000004: three significant digits.
    chart
        .configure_mesh()
        .x_desc(xl)
        .y_desc(yl)
        .x_label_formatter(&|v| short_number(*v))
        .y_label_formatter(&|v| short_number(*v))
        .draw()?;
    if let Some(l) = level {
        chart.draw_series(DashedLineSeries::new(
            [(x0 / 2.0, l), (x1 * 2.0, l)],
            6,
            4,
            BLACK.stroke_width(1),
        ))?;
    }
    for (k, (name, pts)) in series.iter().enumerate() {
        let c = colour(k);
        if pts.len() > 1 {
            chart.draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?;
        }
        chart.draw_series(pts.iter().map(|p| Circle::new(*p, 5, c.filled())))?;
        if let Some(last) = pts.last() {
            chart.draw_series(std::iter::once(Text::new(
                (*name).clone(),
                *last,
                ("sans-serif", 11).into_font(),
            )))?;
        }
    }
    if front {
        // The Pareto front: no other point is both cheaper and more accurate.
        let last: Vec<(f64, f64)> = series
            .iter()
            .filter_map(|(_, p)| p.last().copied())
            .collect();
        let mut f: Vec<(f64, f64)> = last
            .iter()
            .filter(|p| {
                !last
                    .iter()
                    .any(|q| q.0 <= p.0 && q.1 <= p.1 && (q.0 < p.0 || q.1 < p.1))
            })
            .copied()
            .collect();
        f.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart.draw_series(LineSeries::new(f, BLACK.stroke_width(1)))?;
    }
    Ok(())
}

/// Each kind's curve `name` as (x, y) points, or its single point (`x`, `y` measures).
fn ladder_series(
    r: &CompareRecord,
    name: &str,
    x: &str,
    y: &str,
) -> Vec<(String, Vec<(f64, f64)>)> {
    r.kinds
        .iter()
        .filter_map(|k| {
            let pts: Vec<(f64, f64)> = match k.curves.get(name) {
                Some(c) if !c.points.is_empty() => c.points.iter().map(|p| (p[0], p[1])).collect(),
                _ => vec![(k.measures.get(x)?.value?, k.measures.get(y)?.value?)],
            };
            Some((k.kind.clone(), pts))
        })
        .collect()
}

fn cost_size<DB: DrawingBackend>(r: &CompareRecord, a: &DrawingArea<DB, Shift>) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    scatter(
        a,
        "Cost of a simulated ms (1 ms steps) against mesh size (dashed: real time)",
        "elements",
        "wall s per simulated ms",
        &ladder_series(r, "cost", "elements", "cost_haptic"),
        false,
        Some(1e-3),
    )
}

fn mesh_convergence<DB: DrawingBackend>(
    r: &CompareRecord,
    a: &DrawingArea<DB, Shift>,
) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let series: Vec<(String, Vec<(f64, f64)>)> =
        ladder_series(r, "ladder_error", "elements", "force_error")
            .into_iter()
            .map(|(n, p)| (n, p.into_iter().map(|(x, y)| (x, y.max(1e-4))).collect()))
            .collect();
    scatter(
        a,
        "Probe force error against mesh size (dashed: 5 %)",
        "elements",
        "relative force error",
        &series,
        false,
        Some(tissue::compare::measure::LADDER_TARGET),
    )
}

/// A tick label with at most three significant digits (0.3, 0.0001, 2e-5, 1500).
fn short_number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-4..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    // Digits after the point that keep three significant ones, trailing zeros dropped.
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn pareto<DB: DrawingBackend>(r: &CompareRecord, a: &DrawingArea<DB, Shift>) -> Result<(), Err>
where
    DB::ErrorType: 'static,
{
    let pts: Vec<(String, Vec<(f64, f64)>)> = r
        .kinds
        .iter()
        .filter_map(|k| {
            let c = k.measures.get("cost_haptic")?.value?;
            let e = k.measures.get("displacement_error")?.value?;
            Some((k.kind.clone(), vec![(c, e.max(1e-4))]))
        })
        .collect();
    scatter(
        a,
        "Error against cost: the Pareto front",
        "wall s per simulated ms (1 ms steps)",
        "surface displacement error (relative)",
        &pts,
        true,
        None,
    )
}

#[cfg(test)]
mod tests {
    use super::short_number;

    #[test]
    fn tick_labels_keep_three_significant_digits() {
        assert_eq!(short_number(0.30000000000000004), "0.3");
        assert_eq!(short_number(0.6000000000000001), "0.6");
        assert_eq!(short_number(0.0001), "0.0001");
        assert_eq!(short_number(0.001234567), "0.00123");
        assert_eq!(short_number(1500.0), "1500");
        assert_eq!(short_number(2e-5), "2.0e-5");
        assert_eq!(short_number(0.0), "0");
    }
}
