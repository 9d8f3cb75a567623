//! Drawing on any plotters backend: a deformed-mesh frame in the style of the paper's figures 8,
//! 10 and 11, a load-displacement curve, a sequence of crack frames.
use std::collections::BTreeMap;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::run::Snapshot;

/// What a frame shows besides the mesh.
#[derive(Clone, Debug, Default)]
pub struct FrameInfo {
    /// Heading, e.g. "(b) stage above, split 3".
    pub heading: String,
    /// Load levels, e.g. "p = 115".
    pub loads: String,
    /// Displacement magnification.
    pub mag: f64,
    /// Stress length scale: a cross arm of `stress_ref` is `stress_len` model units long.
    pub stress_ref: f64,
    pub stress_len: f64,
    /// Model-space box to show (min x, max x, min y, max y), shared by the frames of a series.
    pub bbox: [f64; 4],
    /// Smaller fonts and no legend samples (panels of a sequence).
    pub compact: bool,
}

pub(crate) fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

const GREY: RGBColor = RGBColor(150, 150, 150);
const JOINED: RGBColor = RGBColor(40, 70, 170);
const OPEN: RGBColor = RGBColor(210, 20, 20);
const HALF: RGBColor = RGBColor(240, 140, 0);
const TENSION: RGBColor = RGBColor(220, 30, 30);
const COMPRESSION: RGBColor = RGBColor(30, 60, 220);

/// Principal stresses (tension positive) of `[sxx, syy, sxy]`: (s_a, s_b, angle of s_a).
pub fn principal(s: [f64; 3]) -> (f64, f64, f64) {
    let c = 0.5 * (s[0] + s[1]);
    let r = (0.25 * (s[0] - s[1]).powi(2) + s[2] * s[2]).sqrt();
    let th = 0.5 * (2.0 * s[2]).atan2(s[0] - s[1]);
    (c + r, c - r, th)
}

/// Box around the reference and the magnified deformed mesh of every snapshot.
pub fn bbox(snaps: &[&Snapshot], mag: f64) -> [f64; 4] {
    let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for s in snaps {
        for c in 0..s.x0.len() {
            for (x, y) in [(s.x0[c][0], s.x0[c][1]), s.x(c, mag)] {
                b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
            }
        }
    }
    let pad = 0.04 * (b[1] - b[0]).max(b[3] - b[2]).max(1e-12);
    [b[0] - pad, b[1] + pad, b[2] - pad, b[3] + pad]
}

/// A range pair with the aspect ratio of a `w` x `h` pixel area (equal scales on x and y).
fn equal_aspect(b: [f64; 4], w: f64, h: f64) -> ([f64; 2], [f64; 2]) {
    let (dx, dy) = (b[1] - b[0], b[3] - b[2]);
    let (cx, cy) = (0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]));
    let s = (dx / w).max(dy / h);
    ([cx - 0.5 * s * w, cx + 0.5 * s * w], [cy - 0.5 * s * h, cy + 0.5 * s * h])
}

/// A "nice" number (1, 2 or 5 times a power of ten) at most `v`.
pub fn nice_floor(v: f64) -> f64 {
    if !(v > 0.0 && v.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(v.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|m| m * p).find(|&x| x <= v).unwrap_or(p)
}

/// Draws one frame: initial mesh dashed grey, deformed mesh (outline solid, joined interior edges
/// dashed), crack faces bold, principal-stress crosses at element centres, legend below.
pub fn frame<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, s: &Snapshot, info: &FrameInfo) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (w, h) = root.dim_in_pixel();
    let fs = if info.compact { 15 } else { 18 };
    let legend_h = if info.compact { 118 } else { 120 };
    let (top, bottom) = root.split_vertically(h.saturating_sub(legend_h));
    let margin = 12u32;
    let (pw, ph) = (w.saturating_sub(2 * margin).max(10) as f64, (h.saturating_sub(legend_h + 2 * margin)).max(10) as f64);
    let (xr, yr) = equal_aspect(info.bbox, pw, ph);
    let mut chart = ChartBuilder::on(&top).margin(margin).build_cartesian_2d(xr[0]..xr[1], yr[0]..yr[1]).map_err(err)?;
    let mag = info.mag;
    // Initial mesh, dashed, one line per mesh edge.
    let mut init: BTreeMap<(i64, i64), (usize, usize)> = BTreeMap::new();
    let mut def: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    for e in &s.elems {
        for k in 0..e.len() {
            let (a, b) = (e[k], e[(k + 1) % e.len()]);
            let (pa, pb) = (s.point[a], s.point[b]);
            init.entry((pa.min(pb), pa.max(pb))).or_insert((a, b));
            *def.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let dash = |pts: Vec<(f64, f64)>, color: RGBColor, width: u32| DashedLineSeries::new(pts, 5, 4, color.stroke_width(width));
    for (a, b) in init.values() {
        chart.draw_series(dash(vec![(s.x0[*a][0], s.x0[*a][1]), (s.x0[*b][0], s.x0[*b][1])], GREY, 1)).map_err(err)?;
    }
    // Deformed mesh: joined interior edges dashed, outline solid.
    for (&(a, b), &n) in &def {
        let pts = vec![s.x(a, mag), s.x(b, mag)];
        if n >= 2 {
            chart.draw_series(dash(pts, JOINED, 1)).map_err(err)?;
        } else {
            chart.draw_series(LineSeries::new(pts, BLACK.stroke_width(2))).map_err(err)?;
        }
    }
    // Crack faces, bold.
    for (f, st) in &s.cracks {
        let color = if *st >= 2 { OPEN } else { HALF };
        chart.draw_series(LineSeries::new(vec![s.x(f[0], mag), s.x(f[1], mag)], color.stroke_width(4))).map_err(err)?;
    }
    // Principal-stress crosses at element centres (deformed).
    if info.stress_ref > 0.0 {
        for (e, st) in s.elems.iter().zip(&s.stress) {
            let n = e.len() as f64;
            let (mut cx, mut cy) = (0.0, 0.0);
            for &c in e {
                let p = s.x(c, mag);
                cx += p.0 / n;
                cy += p.1 / n;
            }
            let (sa, sb, th) = principal(*st);
            for (v, ang) in [(sa, th), (sb, th + std::f64::consts::FRAC_PI_2)] {
                let l = 0.5 * info.stress_len * v.abs() / info.stress_ref;
                if !(l.is_finite() && l > 0.0) {
                    continue;
                }
                let (dx, dy) = (l * ang.cos(), l * ang.sin());
                let col = if v >= 0.0 { TENSION } else { COMPRESSION };
                chart.draw_series(LineSeries::new(vec![(cx - dx, cy - dy), (cx + dx, cy + dy)], col.stroke_width(2))).map_err(err)?;
            }
        }
    }
    // Legend: the heading, the load levels with the magnification and the stress scale, then a
    // key of every line kind (wrapped to the frame's width; in the compact panels of the crack
    // sequence too).
    let font = ("sans-serif", fs).into_font();
    let text = |area: &DrawingArea<DB, Shift>, t: &str, x: i32, y: i32| area.draw(&Text::new(t.to_string(), (x, y), font.clone())).map_err(err);
    text(&bottom, &info.heading, 12, 4)?;
    let sig = |v: f64| if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) { format!("{v:.3e}") } else { fmt_num(v) };
    let scale = match (info.stress_ref > 0.0, info.compact) {
        (false, _) => String::new(),
        (true, false) => format!("; a stress cross arm of {} (stress units) is {} length units long", sig(info.stress_ref), sig(info.stress_len)),
        (true, true) => format!("; cross arm {} = {} long", sig(info.stress_ref), sig(info.stress_len)),
    };
    text(&bottom, &format!("{}   displacements x {}{}", info.loads, fmt_num(mag), scale), 12, 4 + fs + 4)?;
    let items: [(&str, RGBColor, u32, bool); 7] = [
        ("initial mesh", GREY, 1, true),
        ("deformed outline", BLACK, 2, false),
        ("joined edge", JOINED, 1, true),
        ("crack face, open at both ends", OPEN, 4, false),
        ("crack face, open at one end", HALF, 4, false),
        ("principal stress, tension", TENSION, 2, false),
        ("compression", COMPRESSION, 2, false),
    ];
    let (mut x, mut y) = (12, 4 + 2 * (fs + 4) + 6);
    for (label, col, wid, dashed) in items {
        let width = 42 + (label.len() as i32) * fs * 55 / 100 + 20;
        if x + width > w as i32 && x > 12 {
            (x, y) = (12, y + fs + 8);
        }
        if dashed {
            let mut k = 0;
            while k < 36 {
                bottom.draw(&PathElement::new(vec![(x + k, y + fs / 2), (x + (k + 5).min(36), y + fs / 2)], col.stroke_width(wid))).map_err(err)?;
                k += 9;
            }
        } else {
            bottom.draw(&PathElement::new(vec![(x, y + fs / 2), (x + 36, y + fs / 2)], col.stroke_width(wid))).map_err(err)?;
        }
        text(&bottom, label, x + 42, y)?;
        x += width;
    }
    Ok(())
}

/// Short number for legends.
pub fn fmt_num(v: f64) -> String {
    if v == v.round() && v.abs() < 1e6 {
        format!("{}", v as i64)
    } else {
        let t = format!("{v:.4}");
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// A load-displacement curve: the history (line) and the stage ends (markers; hollow when the
/// stage did not reach equilibrium).
/// `note` (may be empty) is written under the title.
/// `saw`: the critical states of an events run (issue 19; empty otherwise), drawn as the
/// saw-tooth of sequentially linear analysis.
#[allow(clippy::too_many_arguments)]
pub fn curve<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    note: &str,
    xlabel: &str,
    ylabel: &str,
    line: &[(f64, f64)],
    ends: &[(f64, f64, bool)],
    saw: &[(f64, f64)],
) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    if !note.is_empty() {
        root.draw(&Text::new(note.to_string(), (100, 44), ("sans-serif", 14).into_font())).map_err(err)?;
    }
    let all = line.iter().copied().chain(ends.iter().map(|e| (e.0, e.1))).chain(saw.iter().copied());
    let (mut x0, mut x1, mut y0, mut y1) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (x, y) in all {
        if x.is_finite() && y.is_finite() {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
    }
    let (dx, dy) = ((x1 - x0).max(1e-30) * 0.05, (y1 - y0).max(1e-30) * 0.05);
    let mut chart =
        ChartBuilder::on(root).caption(title, ("sans-serif", 22)).margin(16).x_label_area_size(50).y_label_area_size(80).build_cartesian_2d((x0 - dx)..(x1 + dx), (y0 - dy)..(y1 + dy)).map_err(err)?;
    chart.configure_mesh().disable_x_mesh().disable_y_mesh().x_desc(xlabel).y_desc(ylabel).label_style(("sans-serif", 15)).axis_desc_style(("sans-serif", 17)).draw().map_err(err)?;
    let faint = RGBColor(120, 150, 230);
    chart
        .draw_series(LineSeries::new(line.iter().copied(), faint.stroke_width(1)))
        .map_err(err)?
        .label("history (relaxation path)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], faint.stroke_width(1)));
    if !saw.is_empty() {
        // Sequentially linear analysis: from the origin to each critical state and back.
        let red = RGBColor(200, 40, 40);
        let mut pts = Vec::with_capacity(3 * saw.len());
        for &p in saw {
            pts.extend([(0.0, 0.0), p]);
        }
        let teeth: Vec<(f64, f64)> = std::iter::once((0.0, 0.0)).chain(saw.iter().copied()).collect();
        chart.draw_series(LineSeries::new(pts, red.mix(0.25).stroke_width(1))).map_err(err)?;
        chart
            .draw_series(LineSeries::new(teeth, red.stroke_width(2)))
            .map_err(err)?
            .label("critical state of each event (saw-tooth)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
    }
    // The static curve: the unloaded state, then the stage ends in equilibrium.
    let path: Vec<(f64, f64)> = std::iter::once((0.0, 0.0)).chain(ends.iter().filter(|e| e.2).map(|e| (e.0, e.1))).collect();
    chart.draw_series(LineSeries::new(path, BLACK.stroke_width(2))).map_err(err)?.label("equilibrium states").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .draw_series(ends.iter().filter(|e| e.2).map(|e| Circle::new((e.0, e.1), 5, BLACK.filled())))
        .map_err(err)?
        .label("stage end, in equilibrium")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, BLACK.filled()));
    chart
        .draw_series(ends.iter().filter(|e| !e.2).map(|e| Circle::new((e.0, e.1), 5, OPEN.stroke_width(2))))
        .map_err(err)?
        .label("stage end, step limit (no equilibrium)")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, OPEN.stroke_width(2)));
    chart.configure_series_labels().position(SeriesLabelPosition::LowerRight).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 15)).draw().map_err(err)?;
    Ok(())
}
