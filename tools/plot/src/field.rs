//! A per-element scalar field on the (deformed) mesh as filled cells with a colour bar: the
//! mechanism picture of `flem fos` (plastic shear strain, issue 21). Drawn on any plotters
//! backend and written by [`crate::render`] as PNG and SVG.
use std::path::{Path, PathBuf};

use flem_core::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::draw::{err, fmt_num};

/// What to draw: cells (corner positions, already displaced if wanted), one value per cell.
pub struct Field<'a> {
    pub title: &'a str,
    /// The quantity and its unit, under the colour bar.
    pub label: &'a str,
    pub cells: &'a [Vec<[f64; 2]>],
    pub values: &'a [f64],
}

/// White (0) through yellow and orange to dark red (1).
fn colour(t: f64) -> RGBColor {
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let stops = [(0.0, [255.0, 255.0, 255.0]), (0.25, [255.0, 235.0, 120.0]), (0.55, [245.0, 140.0, 30.0]), (0.8, [200.0, 30.0, 20.0]), (1.0, [90.0, 0.0, 10.0])];
    let k = stops.iter().rposition(|s| s.0 <= t).unwrap_or(0).min(stops.len() - 2);
    let (a, b) = (stops[k], stops[k + 1]);
    let w = (t - a.0) / (b.0 - a.0);
    let c = |i: usize| (a.1[i] + w * (b.1[i] - a.1[i])).round() as u8;
    RGBColor(c(0), c(1), c(2))
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, f: &Field, bbox: [f64; 4], vmax: f64) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (w, h) = root.dim_in_pixel();
    let (top, bottom) = root.split_vertically(h.saturating_sub(90));
    let (pw, ph) = ((w - 24) as f64, (h - 90 - 24) as f64);
    let s = ((bbox[1] - bbox[0]) / pw).max((bbox[3] - bbox[2]) / ph);
    let (cx, cy) = (0.5 * (bbox[0] + bbox[1]), 0.5 * (bbox[2] + bbox[3]));
    let mut chart = ChartBuilder::on(&top).margin(12).build_cartesian_2d(cx - 0.5 * s * pw..cx + 0.5 * s * pw, cy - 0.5 * s * ph..cy + 0.5 * s * ph).map_err(err)?;
    for (c, &v) in f.cells.iter().zip(f.values) {
        let pts: Vec<(f64, f64)> = c.iter().map(|p| (p[0], p[1])).collect();
        chart.draw_series(std::iter::once(Polygon::new(pts.clone(), colour(v / vmax).filled()))).map_err(err)?;
        let mut ring = pts;
        ring.push(ring[0]);
        chart.draw_series(std::iter::once(PathElement::new(ring, RGBColor(170, 170, 170).stroke_width(1)))).map_err(err)?;
    }
    let font = ("sans-serif", 18).into_font();
    bottom.draw(&Text::new(f.title.to_string(), (12, 4), font.clone())).map_err(err)?;
    // Colour bar: 0 .. vmax.
    let (x0, y0, bw) = (12i32, 34i32, (w as i32 - 24).min(500));
    for k in 0..bw {
        let c = colour(k as f64 / bw as f64);
        bottom.draw(&PathElement::new(vec![(x0 + k, y0), (x0 + k, y0 + 16)], c.stroke_width(1))).map_err(err)?;
    }
    bottom.draw(&Rectangle::new([(x0, y0), (x0 + bw, y0 + 16)], BLACK.stroke_width(1))).map_err(err)?;
    let small = ("sans-serif", 15).into_font();
    bottom.draw(&Text::new("0".to_string(), (x0, y0 + 20), small.clone())).map_err(err)?;
    let top_label = if vmax >= 1e-2 && vmax < 1e4 { fmt_num((vmax * 1e4).round() / 1e4) } else { format!("{vmax:.3e}") };
    bottom.draw(&Text::new(top_label, (x0 + bw - 50, y0 + 20), small.clone())).map_err(err)?;
    bottom.draw(&Text::new(f.label.to_string(), (x0 + bw + 16, y0), small)).map_err(err)?;
    Ok(())
}

/// Draws `f` into `stem`.png and `stem`.svg (width 1100 pixels, the height from the mesh).
pub fn element_field(stem: &Path, f: &Field) -> Result<Vec<PathBuf>> {
    let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for p in f.cells.iter().flatten() {
        b = [b[0].min(p[0]), b[1].max(p[0]), b[2].min(p[1]), b[3].max(p[1])];
    }
    let pad = 0.03 * (b[1] - b[0]).max(b[3] - b[2]).max(1e-12);
    let b = [b[0] - pad, b[1] + pad, b[2] - pad, b[3] + pad];
    let w = 1100u32;
    let r = ((b[3] - b[2]) / (b[1] - b[0])).clamp(0.2, 2.0);
    let h = (w as f64 * r) as u32 + 90;
    let vmax = f.values.iter().copied().filter(|v| v.is_finite()).fold(0.0, f64::max);
    let vmax = if vmax > 0.0 { vmax } else { 1.0 };
    crate::render(stem, (w, h), |a| draw(a, f, b, vmax), |a| draw(a, f, b, vmax))
}
