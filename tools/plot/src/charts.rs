//! Charts of numbers rather than of a run: the speed-accuracy chart of `flem chart` and the
//! stability map of `flem stability` (issue 9). Log-log where the quantities span decades.
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::draw::err;
use crate::render;
use flem_core::Result;

/// One point of the speed-accuracy chart.
#[derive(Clone, Debug)]
pub struct ChartPoint {
    /// Series name (e.g. "adaptive x2", "implicit").
    pub series: String,
    pub wall_seconds: f64,
    pub error: f64,
    pub pareto: bool,
}

const PALETTE: [RGBColor; 8] =
    [RGBColor(31, 119, 180), RGBColor(255, 127, 14), RGBColor(44, 160, 44), RGBColor(214, 39, 40), RGBColor(148, 103, 189), RGBColor(140, 86, 75), RGBColor(227, 119, 194), RGBColor(127, 127, 127)];

fn log_range(v: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for x in v.filter(|x| x.is_finite() && *x > 0.0) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return 1e-3..1.0;
    }
    (lo / 2.0)..(hi * 2.0).max(lo * 4.0)
}

fn speed_accuracy_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, err_label: &str, pts: &[ChartPoint]) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let floor = pts.iter().map(|p| p.error).filter(|e| *e > 0.0).fold(f64::INFINITY, f64::min).min(1e-16);
    let y = |e: f64| if e > 0.0 { e } else { floor };
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(log_range(pts.iter().map(|p| p.wall_seconds)).log_scale(), log_range(pts.iter().map(|p| y(p.error))).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("wall time (s)")
        .y_desc(err_label)
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(err)?;
    let mut series: Vec<&str> = Vec::new();
    for p in pts {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    for (i, s) in series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let these: Vec<(f64, f64)> = pts.iter().filter(|p| p.series == *s).map(|p| (p.wall_seconds, y(p.error))).collect();
        if s.starts_with("implicit") {
            chart.draw_series(these.iter().map(|&(x, e)| TriangleMarker::new((x, e), 8, c.filled()))).map_err(err)?.label(*s).legend(move |(x, y)| TriangleMarker::new((x + 10, y), 7, c.filled()));
        } else {
            chart.draw_series(these.iter().map(|&(x, e)| Circle::new((x, e), 5, c.filled()))).map_err(err)?.label(*s).legend(move |(x, y)| Circle::new((x + 10, y), 5, c.filled()));
        }
    }
    let mut front: Vec<(f64, f64)> = pts.iter().filter(|p| p.pareto).map(|p| (p.wall_seconds, y(p.error))).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(front.clone(), BLACK.stroke_width(2))).map_err(err)?.label("Pareto front").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart.draw_series(front.iter().map(|&(x, e)| Circle::new((x, e), 8, BLACK.stroke_width(2)))).map_err(err)?;
    chart.configure_series_labels().position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 14)).draw().map_err(err)?;
    Ok(())
}

/// The speed-accuracy chart (`stem`.png and `stem`.svg).
pub fn speed_accuracy(stem: &Path, title: &str, err_label: &str, pts: &[ChartPoint]) -> Result<Vec<PathBuf>> {
    render(stem, (1000, 700), |r| speed_accuracy_on(r, title, err_label, pts), |r| speed_accuracy_on(r, title, err_label, pts))
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
        .x_desc("measured threshold / prediction (1: exact; < 1: unsafe)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    c.draw_series(LineSeries::new(vec![(1.0, -0.5), (1.0, n as f64 - 0.5)], BLACK.stroke_width(2))).map_err(err)?;
    c.draw_series(d.thresholds.iter().enumerate().map(|(i, t)| {
        let col = if t.1 < 0.98 { RGBColor(214, 39, 40) } else { RGBColor(31, 119, 180) };
        Circle::new((t.1, i as f64), 6, col.filled())
    }))
    .map_err(err)?;
    let xr = log_range(d.damping.iter().map(|x| x.1));
    let yr = log_range(d.damping.iter().map(|x| x.2));
    let mut c = ChartBuilder::on(&right)
        .caption("damping: steps to rest (ratio 1e-8)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(xr.log_scale(), yr.log_scale())
        .map_err(err)?;
    c.configure_mesh().x_desc("damping parameter (local ratio; viscous alpha / 2 omega_1)").y_desc("steps").label_style(("sans-serif", 13)).draw().map_err(err)?;
    let mut series: Vec<&str> = Vec::new();
    for x in &d.damping {
        if !series.contains(&x.0.as_str()) {
            series.push(&x.0);
        }
    }
    for (i, s) in series.iter().enumerate() {
        let col = PALETTE[i % PALETTE.len()];
        let pts: Vec<(f64, f64, bool)> = d.damping.iter().filter(|x| x.0 == *s).map(|x| (x.1, x.2, x.3)).collect();
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
    c.configure_mesh().x_desc("element size h (mean edge)").y_desc("initiation load factor p_crit").x_label_formatter(&|v| format!("{v:.3}")).label_style(("sans-serif", 14)).draw().map_err(err)?;
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
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    c.configure_mesh().label_style(("sans-serif", 13)).draw().map_err(err)?;
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
