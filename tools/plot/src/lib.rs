//! `flem-plot`: pictures of a FLEM run folder, in the style of the paper's figures (Nishimura et
//! al., figures 8, 10 and 11): the initial mesh dashed, the deformed mesh solid with a
//! magnification factor, crack faces bold and still-joined edges dashed, principal-stress
//! crosses scaled, a legend with the load levels; a load-displacement curve; a sequence of four
//! frames of the crack running (figure 11 (a)-(d)).
//!
//! Input is only what a run writes (`results.pvd` and its VTU files read back with vtkio,
//! `history.csv`, `summary.json`), so `flem plot RUN_DIR` works on any finished run. Damaged
//! input is refused before any picture is drawn, as `FILE:LINE: what` ([`run::History::read`],
//! [`run::stages`], [`run::snapshot_list`]); what a kill leaves (a last history line cut, no
//! summary.json) is drawn up to what is whole and said in [`PlotReport::notes`]. Output goes
//! into `RUN_DIR/plots/` as PNG (plotters' bitmap backend, encoded in memory with `png`) and SVG,
//! every file through `flem_core::output::atomic_write`.
//!
//! Text uses DejaVu Sans, bundled (`fonts/DejaVuSans.ttf`, Bitstream Vera licence with public
//! domain DejaVu changes: `fonts/LICENSE-DejaVu.txt`) and registered with plotters' `ab_glyph`
//! feature, so no system font or library is needed.
//!
//! # How (issue 8)
//! Reading only what a run wrote keeps this crate independent of the solver: `flem plot DIR`,
//! `flem run --plot`, or `[output] plots = true`. `run.rs` reads, `draw.rs` draws on any
//! plotters backend (frame, curve), this file renders each picture twice (bitmap into memory,
//! PNG-encoded with `png`; SVG into a string) and writes both with `output::atomic_write`. The
//! font is registered once. The magnification and stress scale come from the snapshots of
//! stages in equilibrium, so a fragment flying off after a full separation does not shrink the
//! picture. Damaged input is never read as NaN or guessed: `history.csv:LINE: ...` for a row
//! with the wrong number of fields, a field that is not a finite number (empty is "not computed
//! yet"), an empty or fractional `step`/`stage`, a step going back; `summary.json:LINE:COL` when
//! it is not JSON (cut), `summary.json: stages[K].KEY` for a damaged stage list;
//! `results.pvd:LINE` for a bad `<DataSet>`. Without summary.json every stage is taken as in
//! equilibrium (a note says so). `splits.csv` is not read by `flem plot`. The charts of
//! `flem chart` and `flem stability` are in `charts.rs`. The paper's scenes and their results:
//! `configs/paper/`, `docs/paper.md`, `tests/paper.rs`.
pub mod charts;
pub mod draw;
pub mod field;
pub mod run;

use std::path::{Path, PathBuf};

use flem_core::output::atomic_write;
use flem_core::{FlemError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

use draw::{err, FrameInfo};
use run::{History, Snapshot};

static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Registers the bundled font as "sans-serif" (once per process).
pub fn register_font() -> Result<()> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(FlemError::Other("the bundled font DejaVuSans.ttf could not be registered".into()))
    }
}

/// Renders with `f` into a PNG and an SVG file (`stem`.png, `stem`.svg), atomically.
pub fn render(
    stem: &Path,
    (w, h): (u32, u32),
    f: impl Fn(&DrawingArea<BitMapBackend, Shift>) -> std::result::Result<(), String>,
    g: impl Fn(&DrawingArea<SVGBackend, Shift>) -> std::result::Result<(), String>,
) -> Result<Vec<PathBuf>> {
    register_font()?;
    let fail = |what: &str, e: String| FlemError::Output { path: format!("{}.{what}", stem.display()), msg: e };
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        f(&root).map_err(|e| fail("png", e))?;
        root.present().map_err(|e| fail("png", err(e)))?;
    }
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Default, not Best: Best spent 73 % of `flem plot`'s time in deflate for 1 % larger
        // files than Default on the opening scene's 14 pictures (0.59 s against 0.35 s, 472 kB
        // against 467 kB); Fast is 0.16 s but 2.8x the bytes.
        enc.set_compression(png::Compression::Default);
        enc.set_filter(png::FilterType::Paeth);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut wr = enc.write_header().map_err(|e| fail("png", err(e)))?;
        wr.write_image_data(&buf).map_err(|e| fail("png", err(e)))?;
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        g(&root).map_err(|e| fail("svg", e))?;
        root.present().map_err(|e| fail("svg", err(e)))?;
    }
    let (p, s) = (stem.with_extension("png"), stem.with_extension("svg"));
    atomic_write(&p, &png_bytes)?;
    atomic_write(&s, svg.as_bytes())?;
    Ok(vec![p, s])
}

/// What `plot_run` drew.
#[derive(Clone, Debug, Default)]
pub struct PlotReport {
    pub files: Vec<PathBuf>,
    pub mag: f64,
    /// Snapshot names of the crack sequence panels.
    pub sequence: Vec<String>,
    /// What the pictures leave out or assume, for the user (`flem plot` prints them): a last
    /// line of history.csv cut by a kill, a missing summary.json.
    pub notes: Vec<String>,
}

/// The stage index of a snapshot file name (`snapshot_NNNN_stageK.vtu` or `..._stageK_...`).
fn stage_of(name: &str) -> Option<usize> {
    let rest = name.split("_stage").nth(1)?;
    rest.trim_end_matches(".vtu").split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

/// Draws every picture of the run folder `dir` into `dir/plots/`.
pub fn plot_run(dir: &Path) -> Result<PlotReport> {
    let list = run::snapshot_list(dir)?;
    if list.is_empty() {
        return Err(FlemError::Other(format!("{}: results.pvd lists no snapshot", dir.display())));
    }
    let snaps: Vec<(f64, Snapshot)> = list.iter().map(|(t, p)| Snapshot::read(p).map(|s| (*t, s))).collect::<Result<_>>()?;
    let hist = History::read(dir)?;
    let mut notes = Vec::new();
    if let Some(n) = hist.cut_line {
        notes.push(format!("{}:{n}: the last line is cut (the run was killed while writing it) and left out: the curves end at line {}", dir.join("history.csv").display(), n - 1));
    }
    let stages = match run::stages(dir)? {
        Some(s) => s,
        None => {
            notes.push(format!("{} is missing (the run did not end: killed?): every stage is taken as in equilibrium", dir.join("summary.json").display()));
            Vec::new()
        }
    };
    let out = dir.join("plots");
    std::fs::create_dir_all(&out).map_err(|e| FlemError::Output { path: out.display().to_string(), msg: e.to_string() })?;
    // Magnification and stress scale from the states in equilibrium (a part flying off after a
    // full separation would otherwise shrink everything else to nothing).
    let settled: Vec<&Snapshot> = snaps.iter().filter(|(_, s)| stage_of(&s.name).and_then(|k| stages.get(k)).is_none_or(|st| st.1)).map(|(_, s)| s).collect();
    let settled = if settled.is_empty() { snaps.iter().map(|(_, s)| s).collect() } else { settled };
    let first = &snaps[0].1;
    let size = {
        let b = draw::bbox(&[first], 0.0);
        (b[1] - b[0]).max(b[3] - b[2])
    };
    let dmax = settled.iter().map(|s| s.max_disp()).fold(0.0, f64::max);
    let mag = if dmax > 0.0 { draw::nice_floor(0.08 * size / dmax).max(1.0) } else { 1.0 };
    let smax = settled
        .iter()
        .flat_map(|s| s.stress.iter())
        .map(|st| {
            let (a, b, _) = draw::principal(*st);
            a.abs().max(b.abs())
        })
        .fold(0.0, f64::max);
    let h_el = {
        let b = draw::bbox(&[first], 0.0);
        ((b[1] - b[0]) * (b[3] - b[2]) / first.elems.len().max(1) as f64).sqrt() * 0.8
    };
    let bbox = draw::bbox(&settled, mag);
    let (w, h) = frame_size(bbox, 1100);
    // Load levels of a snapshot: those of its stage (the stage's last history row), else the
    // history row nearest in time.
    let levels = |t: f64, name: &str| -> String {
        let names = hist.loads();
        let by_stage = stage_of(name).and_then(|k| hist.col("stage").and_then(|sc| hist.rows.iter().rev().find(|r| r[sc] as usize == k)));
        match by_stage.or_else(|| hist.at_time(t)) {
            Some(row) => names.iter().map(|n| format!("{n} = {}", draw::fmt_num(hist.col(&format!("level_{n}")).map(|c| row[c]).unwrap_or(f64::NAN)))).collect::<Vec<_>>().join(", "),
            None => String::new(),
        }
    };
    let info_for =
        |t: f64, name: &str, heading: String, compact: bool| FrameInfo { heading, loads: format!("load levels: {}", levels(t, name)), mag, stress_ref: smax, stress_len: h_el, bbox, compact };
    let mut rep = PlotReport { mag, notes, ..Default::default() };
    for (k, (t, s)) in snaps.iter().enumerate() {
        let label = s.name.trim_start_matches("snapshot_").trim_end_matches(".vtu").to_string();
        let info = info_for(*t, &s.name, format!("{label}: {} crack faces ({} open at both ends), t = {t:.4e}", s.crack_faces(), s.open_faces()), false);
        rep.files.extend(render(&out.join(format!("frame_{k:04}")), (w, h), |a| draw::frame(a, s, &info), |a| draw::frame(a, s, &info))?);
    }
    // Crack sequence (figure 11 (a)-(d)): the last frame before the crack grows, then three
    // frames spread over the growth up to the last one.
    let c0 = first.crack_faces();
    if let Some(i0) = snaps.iter().position(|(_, s)| s.crack_faces() > c0) {
        let last = snaps.len() - 1;
        let mut pick = vec![i0.saturating_sub(1), i0, i0 + (last - i0) / 2, last];
        pick.dedup();
        let panels: Vec<(FrameInfo, &Snapshot)> = pick
            .iter()
            .enumerate()
            .map(|(j, &i)| {
                let (t, s) = &snaps[i];
                let tag = ["(a)", "(b)", "(c)", "(d)"][j];
                (info_for(*t, &s.name, format!("{tag} {}: {} crack faces", s.name.trim_start_matches("snapshot_").trim_end_matches(".vtu"), s.crack_faces()), true), s)
            })
            .collect();
        rep.sequence = panels.iter().map(|p| p.1.name.clone()).collect();
        let (pw, ph) = frame_size(bbox, 700);
        let cols = 2u32;
        let rows = (panels.len() as u32).div_ceil(cols);
        rep.files.extend(render(
            &out.join("crack_sequence"),
            (cols * pw, rows * ph),
            |a| {
                let areas = a.split_evenly((rows as usize, cols as usize));
                for (j, (info, s)) in panels.iter().enumerate() {
                    draw::frame(&areas[j], s, info)?;
                }
                Ok(())
            },
            |a| {
                let areas = a.split_evenly((rows as usize, cols as usize));
                for (j, (info, s)) in panels.iter().enumerate() {
                    draw::frame(&areas[j], s, info)?;
                }
                Ok(())
            },
        )?);
    }
    if hist.rows.is_empty() {
        // A run stopped before its first history row (Ctrl-C early; its summary writes the header).
        rep.notes.push(format!("{} has no rows: no load-displacement curve", dir.join("history.csv").display()));
    } else {
        rep.files.extend(load_curve(dir, &hist, &stages, &out)?);
    }
    Ok(rep)
}

/// Pixel size of a frame of model box `b`, `w` wide, plus the legend.
fn frame_size(b: [f64; 4], w: u32) -> (u32, u32) {
    let r = ((b[3] - b[2]) / (b[1] - b[0]).max(1e-30)).clamp(0.2, 2.0);
    (w, (w as f64 * r) as u32 + 130)
}

/// The direction of a load as the run's resolved scene gives it: a traction or point load whose
/// value is two numbers points along them; anything else (a pressure, whose direction is each
/// edge's normal, an expression, a prescribed motion) has none here. A scene file that cannot be
/// read gives none (the curve then shows the component that moves most).
fn load_direction(dir: &Path, load: &str) -> Option<[f64; 2]> {
    let text = std::fs::read_to_string(dir.join("scene.resolved.toml")).ok()?;
    let doc: toml::Table = toml::from_str(&text).ok()?;
    let l = doc.get("load")?.as_array()?.iter().find(|l| l.get("name").and_then(|n| n.as_str()) == Some(load))?;
    if !matches!(l.get("type")?.as_str()?, "traction" | "point") {
        return None;
    }
    let v = l.get("value")?.as_array()?;
    let num = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
    let (x, y) = (num(v.first()?)?, num(v.get(1)?)?);
    let n = x.hypot(y);
    (n > 0.0 && n.is_finite()).then_some([x / n, y / n])
}

/// The load-displacement curve of every stage: the load whose level goes highest against a
/// probe's displacement along that load (the probe that moves most that way; the component that
/// moves most when the load has no fixed direction). Stage ends in equilibrium are filled, the
/// others hollow, every stage's end drawn; history rows far beyond the equilibrium states (a
/// fragment flying off after a full separation) are left off the line and counted in the title.
fn load_curve(dir: &Path, hist: &History, stages: &[(String, bool, u64)], out: &Path) -> Result<Vec<PathBuf>> {
    let Some(sc) = hist.col("stage") else { return Ok(Vec::new()) };
    let loads = hist.loads();
    let maxabs = |c: usize| hist.rows.iter().map(|r| r[c]).filter(|v| v.is_finite()).fold(0.0f64, |a, v| a.max(v.abs()));
    // Ties go to the first load of the scene (max_by keeps the last of equals: walk backwards).
    let Some(load) = loads.iter().rev().max_by(|a, b| maxabs(hist.col(&format!("level_{a}")).unwrap()).total_cmp(&maxabs(hist.col(&format!("level_{b}")).unwrap()))) else { return Ok(Vec::new()) };
    let lc = hist.col(&format!("level_{load}")).unwrap();
    // Stage ends: the last row of each stage.
    let mut ends: Vec<(usize, usize)> = Vec::new();
    for (i, r) in hist.rows.iter().enumerate() {
        let st = r[sc] as usize;
        match ends.last_mut() {
            Some(e) if e.0 == st => e.1 = i,
            _ => ends.push((st, i)),
        }
    }
    let conv = |st: usize| stages.get(st).is_none_or(|s| s.1);
    // Candidate displacement measures: per probe, the displacement along the load's direction;
    // without a direction, each probe component.
    let probes: Vec<String> = hist.header.iter().filter_map(|h| h.strip_suffix("_ux").map(str::to_string)).filter(|p| hist.col(&format!("{p}_uy")).is_some()).collect();
    let direction = load_direction(dir, load);
    let measures: Vec<(String, Box<dyn Fn(&[f64]) -> f64>)> = match direction {
        Some(d) => probes
            .iter()
            .map(|p| {
                let (cx, cy) = (hist.col(&format!("{p}_ux")).unwrap(), hist.col(&format!("{p}_uy")).unwrap());
                (format!("displacement of probe {p} along load {load} ({}, {})", fmt_dir(d[0]), fmt_dir(d[1])), Box::new(move |r: &[f64]| r[cx] * d[0] + r[cy] * d[1]) as Box<dyn Fn(&[f64]) -> f64>)
            })
            .collect(),
        None => hist
            .header
            .iter()
            .enumerate()
            .filter(|(_, h)| h.ends_with("_ux") || h.ends_with("_uy"))
            .map(|(c, h)| (format!("{h} (load {load} has no fixed direction)"), Box::new(move |r: &[f64]| r[c]) as Box<dyn Fn(&[f64]) -> f64>))
            .collect(),
    };
    let settled_max = |m: &dyn Fn(&[f64]) -> f64| ends.iter().filter(|e| conv(e.0)).map(|e| m(&hist.rows[e.1]).abs()).filter(|v| v.is_finite()).fold(0.0f64, f64::max);
    let Some((label, m)) = measures.iter().max_by(|a, b| settled_max(a.1.as_ref()).total_cmp(&settled_max(b.1.as_ref()))) else { return Ok(Vec::new()) };
    // An events run (issue 19): the critical state of each event, the same measure on the
    // `<probe>_ux_critical` columns against `critical_level_<load>`.
    let mut saw: Vec<(f64, f64)> = Vec::new();
    if let (Some(cl), Some(d)) = (hist.col(&format!("critical_level_{load}")), direction) {
        if let Some(p) = probes.iter().find(|p| label.starts_with(&format!("displacement of probe {p} along"))) {
            if let (Some(cx), Some(cy)) = (hist.col(&format!("{p}_ux_critical")), hist.col(&format!("{p}_uy_critical"))) {
                saw = hist.rows.iter().map(|r| (r[cx] * d[0] + r[cy] * d[1], r[cl])).filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
                saw.dedup();
            }
        }
    }
    let all_max = hist.rows.iter().map(|r| m(r).abs()).filter(|v| v.is_finite()).fold(0.0f64, f64::max);
    let dmax = settled_max(m.as_ref());
    let limit = if dmax > 0.0 { 3.0 * dmax } else { all_max };
    let keep = |x: f64| x.is_finite() && x.abs() <= limit;
    let line: Vec<(f64, f64)> = hist.rows.iter().map(|r| (m(r), r[lc])).filter(|p| keep(p.0) && p.1.is_finite()).collect();
    let off = hist.rows.iter().filter(|r| !keep(m(r))).count();
    // Every stage's end is drawn; one far beyond the equilibrium states (a fragment flying off)
    // sits at the edge of the chart, its true value in the title, so that the equilibrium branch
    // keeps its scale. History rows that far are left off the line.
    let mut far = Vec::new();
    let pts: Vec<(f64, f64, bool)> = ends
        .iter()
        .map(|e| (e.0, m(&hist.rows[e.1]), hist.rows[e.1][lc], conv(e.0)))
        .filter(|p| p.1.is_finite() && p.2.is_finite())
        .map(|(st, x, y, c)| {
            if keep(x) {
                (x, y, c)
            } else {
                far.push(format!("stage {} ends at {x:.3e}", st + 1));
                (x.signum() * limit, y, c)
            }
        })
        .collect();
    let run = dir.file_name().map(|f| f.to_string_lossy().to_string()).unwrap_or_default();
    let title = format!("load {load}, every stage ({run})");
    let mut notes = Vec::new();
    if off > 0 {
        notes.push(format!("{off} history rows beyond 3x the equilibrium range left off"));
    }
    if !far.is_empty() {
        notes.push(format!("drawn at the edge: {}", far.join(", ")));
    }
    let note = notes.join("; ");
    let (xl, yl) = (format!("{label} (length units)"), format!("level of load {load}"));
    render(&out.join("load_displacement"), (900, 620), |a| draw::curve(a, &title, &note, &xl, &yl, &line, &pts, &saw), |a| draw::curve(a, &title, &note, &xl, &yl, &line, &pts, &saw))
}

fn fmt_dir(v: f64) -> String {
    let t = format!("{v:.3}");
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}
