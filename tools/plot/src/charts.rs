//! Charts of numbers rather than of a run: the speed-accuracy chart of `flem chart` and
//! `flem chart-crack`, the stability map of `flem stability` (issue 9), the picture of
//! `flem converge`. Log-log where the quantities span decades.
//!
//! Readable (issue 40): in the speed-accuracy chart one visual channel per dimension, colour =
//! method, marker shape = mesh, marker fill = element kind ([`series_styles`]; colour-blind-safe
//! Okabe-Ito colours, a method keeps its colour from chart to chart), one legend entry per
//! series, drawn beside the plot (plotters' series labels sit inside the plot and covered
//! points). Log axes come from [`log_axis`], not from plotters' own key points, which label
//! every minor tick of a short axis ("8e09e01e1"): decades (every second one past nine), or
//! 1-2-5 below three decades; zeros on a line of their own labelled 0; an axis whose points all
//! have one value gets one labelled tick and a note beside the legend. Every axis names its unit.
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::draw::err;
use crate::render;
use flem_core::{FlemError, Result};

/// One point of the speed-accuracy chart. One visual channel per dimension: the colour is the
/// method, the marker shape the mesh (or the one setting that varies instead), the marker fill
/// the element kind; a series is one (method, element, mesh) and has its own legend entry.
#[derive(Clone, Debug)]
pub struct ChartPoint {
    /// Method, drawn as the colour: "implicit (faer)", "explicit adaptive", "events (ours)".
    pub method: String,
    /// Element kind, drawn as the marker fill (first kind filled, second hollow, third hollow
    /// with a dot); "" when the chart has one kind.
    pub element: String,
    /// Mesh or setting, drawn as the marker shape ("x1", "x2", "tolerance 1e-4"); "" for one.
    pub mesh: String,
    pub wall_seconds: f64,
    pub error: f64,
    pub pareto: bool,
}

/// Marker shapes, in the order the meshes of a chart get them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Shape {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
}

/// Marker fills, in the order the element kinds of a chart get them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Fill {
    Filled,
    Hollow,
    Dotted,
}

const SHAPES: [Shape; 5] = [Shape::Circle, Shape::Square, Shape::TriangleUp, Shape::Diamond, Shape::TriangleDown];
const FILLS: [Fill; 3] = [Fill::Filled, Fill::Hollow, Fill::Dotted];

/// How one series is drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesStyle {
    pub method: String,
    pub element: String,
    pub mesh: String,
    /// The legend entry: "method, element mesh" (empty parts left out).
    pub label: String,
    pub colour: RGBColor,
    pub shape: Shape,
    pub fill: Fill,
}

/// Colour-blind-safe colours (Okabe & Ito), black kept for the Pareto front.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(110, 110, 110), // grey
    RGBColor(140, 86, 75),   // brown
];

/// The colour a method gets when it is free, so that a method keeps its colour from chart to
/// chart (e.g. "explicit adaptive" with or without the implicit points beside it).
fn preferred_colour(method: &str) -> usize {
    let m = method.to_ascii_lowercase();
    [("implicit", 0), ("events", 0), ("adaptive", 1), ("local", 2), ("viscous_eta", 3), ("viscous", 4), ("none", 5), ("explicit", 1)].iter().find(|(k, _)| m.contains(k)).map_or(0, |p| p.1)
}

fn first_seen<'a>(it: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut v: Vec<&str> = Vec::new();
    for s in it {
        if !v.contains(&s) {
            v.push(s);
        }
    }
    v
}

/// The style of every series of `pts` (in order of first appearance): colour by method, shape
/// by mesh, fill by element kind. No two series are drawn alike; more methods, meshes or element
/// kinds than there are colours (8), shapes (5) or fills (3) is an error, not a repeated style.
pub fn series_styles(pts: &[ChartPoint]) -> Result<Vec<SeriesStyle>> {
    let methods = first_seen(pts.iter().map(|p| p.method.as_str()));
    let elements = first_seen(pts.iter().map(|p| p.element.as_str()));
    let meshes = first_seen(pts.iter().map(|p| p.mesh.as_str()));
    let too_many = |what: &str, n: usize, max: usize, names: &[&str]| FlemError::Other(format!("speed-accuracy chart: {n} {what} ({names:?}), more than the {max} that can be told apart"));
    if methods.len() > PALETTE.len() {
        return Err(too_many("methods", methods.len(), PALETTE.len(), &methods));
    }
    if meshes.len() > SHAPES.len() {
        return Err(too_many("meshes", meshes.len(), SHAPES.len(), &meshes));
    }
    if elements.len() > FILLS.len() {
        return Err(too_many("element kinds", elements.len(), FILLS.len(), &elements));
    }
    let mut colour = vec![usize::MAX; methods.len()];
    for (i, m) in methods.iter().enumerate() {
        let want = preferred_colour(m);
        let c = if colour.contains(&want) { (0..PALETTE.len()).find(|c| !colour.contains(c)).unwrap_or(0) } else { want };
        colour[i] = c;
    }
    let series = first_seen(pts.iter().map(|p| p.series_key()).collect::<Vec<_>>().iter().map(|s| s.as_str()))
        .into_iter()
        .map(|k| pts.iter().find(|p| p.series_key() == k).expect("a point of the series"))
        .map(|p| {
            let mi = methods.iter().position(|m| *m == p.method).unwrap_or(0);
            let label = [p.method.as_str(), &[p.element.as_str(), p.mesh.as_str()].iter().filter(|s| !s.is_empty()).copied().collect::<Vec<_>>().join(" ")]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(", ");
            SeriesStyle {
                method: p.method.clone(),
                element: p.element.clone(),
                mesh: p.mesh.clone(),
                label,
                colour: PALETTE[colour[mi]],
                shape: SHAPES[meshes.iter().position(|m| *m == p.mesh).unwrap_or(0)],
                fill: FILLS[elements.iter().position(|e| *e == p.element).unwrap_or(0)],
            }
        })
        .collect();
    Ok(series)
}

impl ChartPoint {
    fn series_key(&self) -> String {
        format!("{}\u{1f}{}\u{1f}{}", self.method, self.element, self.mesh)
    }
}

/// A log axis: its range, labelled ticks (decades, or 1-2-5 / 1..9 when the axis spans less
/// than three decades), unlabelled grid lines, where a value 0 is drawn, notes for the reader.
#[derive(Clone, Debug, PartialEq)]
pub struct LogAxis {
    pub range: std::ops::Range<f64>,
    pub bold: Vec<f64>,
    pub light: Vec<f64>,
    /// Where the points of value 0 are drawn (a decade below the smallest positive value; its
    /// tick reads "0").
    pub zero: Option<f64>,
    pub notes: Vec<String>,
}

impl LogAxis {
    /// Where `v` is drawn (0 on the zero line).
    pub fn at(&self, v: f64) -> f64 {
        match self.zero {
            Some(z) if v <= 0.0 => z,
            _ => v,
        }
    }
    /// The tick label of `v`: "0" on the zero line; plain decimals when every tick lies in
    /// [1e-3, 1e4), else "2e-5"; three significant digits for a tick that is not 1, 2 or 5 x 10^k.
    pub fn label(&self, v: f64) -> String {
        if self.zero.is_some_and(|z| (v / z - 1.0).abs() < 1e-9) {
            return "0".into();
        }
        let plain = self.bold.iter().filter(|b| Some(**b) != self.zero).all(|b| (1e-3..1e4).contains(b));
        let e = v.log10().floor();
        let m = v / 10f64.powf(e);
        let round = (m - m.round()).abs() < 1e-9;
        if plain {
            let d = (2.0 - e).max(0.0) as usize;
            let t = format!("{v:.d$}");
            if t.contains('.') {
                t.trim_end_matches('0').trim_end_matches('.').to_string()
            } else {
                t
            }
        } else if round {
            format!("{v:.0e}")
        } else {
            format!("{v:.2e}")
        }
    }
}

/// The log axis of `values` (`what`: the quantity, for the notes). Non-finite and negative
/// values are left out; zeros are drawn on a line of their own, a decade below the rest; an
/// axis whose values are all the same gets one labelled tick at that value and a note.
pub fn log_axis(values: &[f64], what: &str) -> LogAxis {
    let pos: Vec<f64> = values.iter().copied().filter(|v| v.is_finite() && *v > 0.0).collect();
    let zeros = values.iter().any(|v| *v == 0.0);
    let half = 10f64.sqrt();
    if pos.is_empty() {
        let notes = if zeros { vec![format!("every point has {what} 0")] } else { vec![format!("no point has a positive {what}")] };
        return LogAxis { range: (1.0 / half)..half, bold: vec![1.0], light: vec![], zero: zeros.then_some(1.0), notes };
    }
    let lo = pos.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = pos.iter().copied().fold(0.0f64, f64::max);
    if hi <= lo * (1.0 + 1e-9) && !zeros {
        return LogAxis { range: (lo / half)..(lo * half), bold: vec![lo], light: vec![], zero: None, notes: vec![format!("every point has {what} {}", sig3(lo))] };
    }
    let zero = zeros.then(|| 10f64.powf(lo.log10().floor() - 1.0));
    let start = zero.unwrap_or(lo) / 1.6;
    let end = hi * 1.6;
    let inside = |v: f64| v >= start && v <= end;
    let (k0, k1) = (start.log10().ceil() as i32, end.log10().floor() as i32);
    let decades: Vec<f64> = (k0..=k1).map(|k| 10f64.powi(k)).collect();
    let mantissas = |ms: &[f64]| -> Vec<f64> { (k0 - 1..=k1).flat_map(|k| ms.iter().map(move |m| m * 10f64.powi(k))).filter(|v| inside(*v)).collect() };
    // Three decades or more: decades; less: 1-2-5 (two decade labels alone say little).
    let (mut bold, mut light) = if decades.len() >= 3 {
        // At most about 9 labels: every `step`-th decade.
        let step = decades.len().div_ceil(9) as i32;
        let bold: Vec<f64> = (k0..=k1).filter(|k| k.rem_euclid(step) == 0).map(|k| 10f64.powi(k)).collect();
        let light = if decades.len() <= 6 { mantissas(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]) } else { decades.clone() };
        (bold, light)
    } else {
        let b125 = mantissas(&[1.0, 2.0, 5.0]);
        if b125.len() >= 2 {
            (b125, mantissas(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]))
        } else {
            (mantissas(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]), Vec::new())
        }
    };
    let mut notes = Vec::new();
    if let Some(z) = zero {
        // The zero line and nothing between it and the decade of the smallest positive value.
        let gap = z * 10.0 * 0.999;
        bold.retain(|v| *v > gap);
        light.retain(|v| *v > gap);
        bold.insert(0, z);
        let n = values.iter().filter(|v| **v == 0.0).count();
        notes.push(format!("{n} point(s) with {what} 0 are drawn on the line labelled 0"));
    }
    LogAxis { range: start..end, bold, light, zero, notes }
}

fn sig3(v: f64) -> String {
    if (1e-3..1e4).contains(&v.abs()) {
        let d = (2.0 - v.abs().log10().floor()).max(0.0) as usize;
        let t = format!("{v:.d$}");
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    } else {
        format!("{v:.2e}")
    }
}

/// Draws a marker of `shape`/`fill`/`colour`, radius about `r` pixels, at `at` of `area`.
fn marker<DB: DrawingBackend, CT: CoordTranslate>(area: &DrawingArea<DB, CT>, at: CT::From, shape: Shape, fill: Fill, colour: RGBColor, r: i32) -> std::result::Result<(), String>
where
    CT::From: Clone,
{
    let pts: Vec<(i32, i32)> = match shape {
        Shape::Circle => Vec::new(),
        Shape::Square => {
            let a = (r * 17) / 20;
            vec![(-a, -a), (a, -a), (a, a), (-a, a)]
        }
        Shape::TriangleUp => {
            let a = r + 1;
            vec![(0, -a), (a, a * 3 / 4), (-a, a * 3 / 4)]
        }
        Shape::TriangleDown => {
            let a = r + 1;
            vec![(0, a), (a, -a * 3 / 4), (-a, -a * 3 / 4)]
        }
        Shape::Diamond => {
            let a = r + 1;
            vec![(0, -a), (a, 0), (0, a), (-a, 0)]
        }
    };
    let solid = colour.filled();
    let line = colour.stroke_width(2);
    let inside = if fill == Fill::Filled { solid } else { WHITE.filled() };
    if shape == Shape::Circle {
        area.draw(&(EmptyElement::at(at.clone()) + Circle::new((0, 0), r, inside))).map_err(err)?;
        if fill != Fill::Filled {
            area.draw(&(EmptyElement::at(at.clone()) + Circle::new((0, 0), r, line))).map_err(err)?;
        }
    } else {
        area.draw(&(EmptyElement::at(at.clone()) + Polygon::new(pts.clone(), inside))).map_err(err)?;
        if fill != Fill::Filled {
            let mut closed = pts;
            closed.push(closed[0]);
            area.draw(&(EmptyElement::at(at.clone()) + PathElement::new(closed, line))).map_err(err)?;
        }
    }
    if fill == Fill::Dotted {
        area.draw(&(EmptyElement::at(at) + Circle::new((0, 0), 2, solid))).map_err(err)?;
    }
    Ok(())
}

/// Splits `text` into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for w in text.split_whitespace() {
        let last = lines.last_mut().expect("one line");
        if !last.is_empty() && last.len() + 1 + w.len() > width {
            lines.push(w.to_string());
        } else {
            if !last.is_empty() {
                last.push(' ');
            }
            last.push_str(w);
        }
    }
    lines
}

/// Width of the legend column of the speed-accuracy chart (pixels).
const LEGEND_W: u32 = 260;

fn speed_accuracy_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, err_label: &str, pts: &[ChartPoint], styles: &[SeriesStyle]) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let body = root.margin(10, 0, 0, 0).titled(title, ("sans-serif", 22)).map_err(err)?;
    let (w, _) = body.dim_in_pixel();
    let (plot, side) = body.split_horizontally(w.saturating_sub(LEGEND_W));
    let xa = log_axis(&pts.iter().map(|p| p.wall_seconds).collect::<Vec<_>>(), "wall time (s)");
    let ya = log_axis(&pts.iter().map(|p| p.error).collect::<Vec<_>>(), "error");
    let mut chart = ChartBuilder::on(&plot)
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(
            xa.range.clone().log_scale().with_key_points(xa.bold.clone()).with_light_points(xa.light.clone()),
            ya.range.clone().log_scale().with_key_points(ya.bold.clone()).with_light_points(ya.light.clone()),
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("wall time (s)")
        .y_desc(err_label)
        .x_label_formatter(&|v| xa.label(*v))
        .y_label_formatter(&|v| ya.label(*v))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(err)?;
    let mut front: Vec<(f64, f64)> =
        pts.iter().filter(|p| p.pareto && p.wall_seconds > 0.0 && p.wall_seconds.is_finite()).map(|p| (p.wall_seconds, ya.at(p.error))).filter(|p| p.1 > 0.0 && p.1.is_finite()).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(front.clone(), BLACK.stroke_width(2))).map_err(err)?;
    let area = chart.plotting_area();
    for s in styles {
        for p in pts.iter().filter(|p| p.method == s.method && p.element == s.element && p.mesh == s.mesh) {
            let (x, y) = (p.wall_seconds, ya.at(p.error));
            if x > 0.0 && x.is_finite() && y > 0.0 && y.is_finite() {
                marker(area, (x, y), s.shape, s.fill, s.colour, 5)?;
            }
        }
    }
    for &(x, e) in &front {
        area.draw(&Circle::new((x, e), 9, BLACK.stroke_width(2))).map_err(err)?;
    }
    // The legend, beside the plot (it covers no point): one entry per series, the front, notes.
    let font = ("sans-serif", 14).into_font().color(&BLACK).pos(Pos::new(HPos::Left, VPos::Center));
    let (mut y, row) = (30i32, 22i32);
    for s in styles {
        marker(&side, (18, y), s.shape, s.fill, s.colour, 5)?;
        side.draw_text(&s.label, &font, (34, y)).map_err(err)?;
        y += row;
    }
    side.draw(&PathElement::new(vec![(6, y), (30, y)], BLACK.stroke_width(2))).map_err(err)?;
    side.draw(&Circle::new((18, y), 9, BLACK.stroke_width(2))).map_err(err)?;
    side.draw_text("Pareto front", &font, (34, y)).map_err(err)?;
    y += row + 10;
    let notes: Vec<String> = xa.notes.iter().chain(&ya.notes).cloned().collect();
    let small = ("sans-serif", 13).into_font();
    for n in &notes {
        for l in wrap(&format!("note: {n}"), 34) {
            side.draw_text(&l, &small.color(&BLACK), (6, y)).map_err(err)?;
            y += 17;
        }
        y += 4;
    }
    Ok(())
}

/// The speed-accuracy chart (`stem`.png and `stem`.svg): log-log wall time (s) against
/// `err_label` (give its unit), colour = method, marker shape = mesh, marker fill = element kind
/// ([`series_styles`]), the Pareto front marked, the legend beside the plot.
pub fn speed_accuracy(stem: &Path, title: &str, err_label: &str, pts: &[ChartPoint]) -> Result<Vec<PathBuf>> {
    let styles = series_styles(pts)?;
    render(stem, (1000 + LEGEND_W, 700), |r| speed_accuracy_on(r, title, err_label, pts, &styles), |r| speed_accuracy_on(r, title, err_label, pts, &styles))
}

/// The stability map's data: blow-up threshold / prediction per case; steps to rest per
/// damping parameter (series name, parameter, steps, came to rest).
#[derive(Clone, Debug, Default)]
pub struct StabilityData {
    pub thresholds: Vec<(String, f64)>,
    pub damping: Vec<(String, f64, f64, bool)>,
}

fn stability_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, d: &StabilityData) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (left, right) = root.split_horizontally(520);
    let n = d.thresholds.len().max(1);
    let lo = d.thresholds.iter().map(|t| t.1).fold(0.9f64, f64::min) - 0.02;
    let hi = d.thresholds.iter().map(|t| t.1).fold(1.1f64, f64::max) + 0.02;
    let mut c = ChartBuilder::on(&left)
        .caption("explicit step and contact stiffness: blow-up / predicted dt_crit", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(170)
        .build_cartesian_2d(lo..hi, -0.5..(n as f64 - 0.5))
        .map_err(err)?;
    let names: Vec<String> = d.thresholds.iter().map(|t| t.0.clone()).collect();
    c.configure_mesh()
        .y_labels(n)
        .y_label_formatter(&|v| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .x_desc("measured threshold / prediction (dimensionless; 1: exact, < 1: unsafe)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    c.draw_series(LineSeries::new(vec![(1.0, -0.5), (1.0, n as f64 - 0.5)], BLACK.stroke_width(2))).map_err(err)?;
    c.draw_series(d.thresholds.iter().enumerate().map(|(i, t)| {
        let col = if t.1 < 0.98 { RGBColor(214, 39, 40) } else { RGBColor(31, 119, 180) };
        Circle::new((t.1, i as f64), 6, col.filled())
    }))
    .map_err(err)?;
    let xa = log_axis(&d.damping.iter().map(|x| x.1).collect::<Vec<_>>(), "damping parameter");
    let ya = log_axis(&d.damping.iter().map(|x| x.2).collect::<Vec<_>>(), "steps");
    let mut c = ChartBuilder::on(&right)
        .caption("damping: steps to rest (ratio 1e-8)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(
            xa.range.clone().log_scale().with_key_points(xa.bold.clone()).with_light_points(xa.light.clone()),
            ya.range.clone().log_scale().with_key_points(ya.bold.clone()).with_light_points(ya.light.clone()),
        )
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("damping parameter (dimensionless: local ratio; viscous alpha / 2 omega_1)")
        .y_desc("steps to rest (count)")
        .x_label_formatter(&|v| xa.label(*v))
        .y_label_formatter(&|v| ya.label(*v))
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    let series = first_seen(d.damping.iter().map(|x| x.0.as_str()));
    let mut used: Vec<usize> = Vec::new();
    for s in &series {
        let want = preferred_colour(s);
        let ci = if used.contains(&want) { (0..PALETTE.len()).find(|c| !used.contains(c)).unwrap_or(0) } else { want };
        used.push(ci);
        let col = PALETTE[ci];
        let pts: Vec<(f64, f64, bool)> = d.damping.iter().filter(|x| x.0 == *s).map(|x| (xa.at(x.1), ya.at(x.2), x.3)).filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
        c.draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.1)), col.stroke_width(2)))
            .map_err(err)?
            .label(*s)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        c.draw_series(pts.iter().map(|p| if p.2 { Circle::new((p.0, p.1), 4, col.filled()) } else { Circle::new((p.0, p.1), 6, col.stroke_width(2)) })).map_err(err)?;
    }
    c.configure_series_labels().position(SeriesLabelPosition::UpperLeft).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 13)).draw().map_err(err)?;
    Ok(())
}

/// The stability map picture (`stem`.png and `stem`.svg); hollow markers: not at rest.
pub fn stability(stem: &Path, d: &StabilityData) -> Result<Vec<PathBuf>> {
    render(stem, (1200, 560), |r| stability_on(r, d), |r| stability_on(r, d))
}

/// One mesh level of `flem converge`: element size, initiation factor of each check
/// (`None`: not computed), crack path of the explicit run (split points).
#[derive(Clone, Debug, Default)]
pub struct ConvergeLevel {
    pub h: f64,
    pub p_local: Option<f64>,
    pub p_nonlocal: Option<f64>,
    pub path: Vec<[f64; 2]>,
}

fn converge_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, lv: &[ConvergeLevel], bounds: [[f64; 2]; 2]) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (left, right) = root.split_horizontally(560);
    let ps: Vec<f64> = lv.iter().flat_map(|l| [l.p_local, l.p_nonlocal]).flatten().filter(|p| p.is_finite()).collect();
    let (lo, hi) = ps.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &p| (a.min(p), b.max(p)));
    let (lo, hi) = if lo.is_finite() { (0.0f64.min(lo), 1.4 * hi) } else { (0.0, 1.0) };
    let hmax = lv.iter().map(|l| l.h).fold(0.0f64, f64::max).max(1e-12);
    let mut c = ChartBuilder::on(&left).caption(title, ("sans-serif", 18)).margin(12).x_label_area_size(45).y_label_area_size(70).build_cartesian_2d(0.0..1.1 * hmax, lo..hi).map_err(err)?;
    c.configure_mesh()
        .x_desc("element size h, mean edge (length units of the scene)")
        .y_desc("initiation load factor p_crit (dimensionless)")
        .x_label_formatter(&|v| format!("{v:.3}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    for (i, (name, get)) in [("local (paper: corner mean)", 0usize), ("nonlocal (ours)", 1)].into_iter().enumerate() {
        let col = PALETTE[i];
        let pts: Vec<(f64, f64)> = lv.iter().filter_map(|l| if get == 0 { l.p_local } else { l.p_nonlocal }.map(|p| (l.h, p))).filter(|p| p.1.is_finite()).collect();
        if pts.is_empty() {
            continue;
        }
        c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2))).map_err(err)?.label(name).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 5, col.filled()))).map_err(err)?;
    }
    c.configure_series_labels().position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 13)).draw().map_err(err)?;
    let [[x0, y0], [x1, y1]] = bounds;
    let mut c = ChartBuilder::on(&right)
        .caption("crack paths (split points: the ramp's, else the run at 1.05 p_crit)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(65)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    c.configure_mesh().x_desc("x (length units of the scene)").y_desc("y (length units of the scene)").label_style(("sans-serif", 13)).draw().map_err(err)?;
    for (i, l) in lv.iter().enumerate() {
        let col = PALETTE[(i + 2) % PALETTE.len()];
        let name = format!("h = {:.4}", l.h);
        c.draw_series(l.path.iter().map(|p| Circle::new((p[0], p[1]), 4 + 2 * (lv.len() - i) as i32, col.stroke_width(2))))
            .map_err(err)?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, col.stroke_width(2)));
    }
    c.configure_series_labels().position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 13)).draw().map_err(err)?;
    Ok(())
}

/// The picture of `flem converge` (`stem`.png and `stem`.svg): p_crit against h for the local
/// and the nonlocal check; the crack paths of all levels overlaid in the body's `bounds`.
pub fn converge(stem: &Path, title: &str, levels: &[ConvergeLevel], bounds: [[f64; 2]; 2]) -> Result<Vec<PathBuf>> {
    render(stem, (1120, 560), |r| converge_on(r, title, levels, bounds), |r| converge_on(r, title, levels, bounds))
}
