//! The charts of `flem chart`, `flem chart-crack`, `flem stability` and `flem converge` (issue
//! 40) rendered on small synthetic cases and read back from their SVG (plotters' SVG backend
//! writes every label as a `<text>` element): the legend has an entry per series, log axes are
//! labelled at decades (or 1-2-5) only and the labels do not overlap, an axis without range
//! gets one readable tick and a note, every axis names its unit. Reference: the data given to
//! the chart (which series, which decades it spans), not an earlier picture.
use std::path::PathBuf;

use flem_plot::charts::{log_axis, series_styles, speed_accuracy, ChartPoint, ConvergeLevel, StabilityData};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("flem_charts_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One `<text>` element of an SVG: position, font size, content (unescaped).
#[derive(Debug)]
struct Text {
    x: f64,
    y: f64,
    size: f64,
    rotated: bool,
    s: String,
}

fn attr(head: &str, name: &str) -> Option<f64> {
    let k = format!(" {name}=\"");
    let i = head.find(&k)? + k.len();
    head[i..].split('"').next()?.parse().ok()
}

fn texts(svg: &str) -> Vec<Text> {
    svg.split("<text")
        .skip(1)
        .map(|t| {
            let (head, rest) = t.split_once('>').unwrap();
            let body = rest.split("</text>").next().unwrap().trim();
            let s = body.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&apos;", "'").replace("&amp;", "&");
            Text { x: attr(head, "x").unwrap(), y: attr(head, "y").unwrap(), size: attr(head, "font-size").unwrap(), rotated: head.contains("rotate("), s }
        })
        .collect()
}

/// The texts that are numbers or "0" (tick labels).
fn ticks(t: &[Text]) -> Vec<&Text> {
    t.iter().filter(|t| !t.rotated && t.s.parse::<f64>().is_ok()).collect()
}

/// No two labels of one row (same y) overlap, width estimated at 0.62 em per character
/// (DejaVu Sans digits are 0.636 em; labels are centred on their x).
fn assert_no_overlap(t: &[&Text]) {
    for a in t {
        for b in t {
            if std::ptr::eq(*a, *b) || (a.y - b.y).abs() > 1.0 {
                continue;
            }
            let half = |t: &Text| 0.31 * t.size * t.s.chars().count() as f64;
            assert!((a.x - b.x).abs() > half(a) + half(b), "tick labels {:?} at x = {} and {:?} at x = {} overlap", a.s, a.x, b.s, b.x);
        }
    }
    // A column of labels (same x, the y axis): at least one font height apart.
    for a in t {
        for b in t {
            if !std::ptr::eq(*a, *b) && (a.x - b.x).abs() < 1.0 {
                assert!((a.y - b.y).abs() > a.size, "tick labels {:?} and {:?} overlap vertically", a.s, b.s);
            }
        }
    }
}

fn pt(method: &str, element: &str, mesh: &str, wall: f64, error: f64, pareto: bool) -> ChartPoint {
    ChartPoint { method: method.into(), element: element.into(), mesh: mesh.into(), wall_seconds: wall, error, pareto }
}

/// The case of docs/img/chart_cantilever_elements.png in small: 3 methods x 2 element kinds x
/// 2 meshes, wall times 1e-3..3 s, errors 1e-4..0.1.
fn elements_case() -> Vec<ChartPoint> {
    let mut v = Vec::new();
    for (ei, el) in ["q4", "qm6"].into_iter().enumerate() {
        for (mi, mesh) in ["x1", "x2"].into_iter().enumerate() {
            for (k, m) in ["implicit (faer)", "explicit adaptive", "explicit local"].into_iter().enumerate() {
                let wall = 1e-3 * 10f64.powf(0.8 * (mi + k) as f64 + 0.1 * ei as f64);
                let error = 1e-1 / 10f64.powi((ei * 2 + mi) as i32) * (1.0 + k as f64);
                v.push(pt(m, el, mesh, wall.min(3.0), error, k == 0));
            }
        }
    }
    v.push(pt("explicit local", "qm6", "x2", 3.0, 1e-4, false));
    v
}

#[test]
fn speed_accuracy_svg_has_every_series_and_decade_ticks() {
    let d = tmp("elements");
    let pts = elements_case();
    let files = speed_accuracy(&d.join("chart"), "speed vs accuracy: test", "relative error vs analytic (dimensionless)", &pts).unwrap();
    assert_eq!(files.len(), 2);
    let svg = std::fs::read_to_string(d.join("chart.svg")).unwrap();
    let t = texts(&svg);
    let all: Vec<&str> = t.iter().map(|t| t.s.as_str()).collect();
    let styles = series_styles(&pts).unwrap();
    assert_eq!(styles.len(), 12);
    for s in &styles {
        assert_eq!(all.iter().filter(|x| **x == s.label).count(), 1, "legend entry {:?} once in {all:?}", s.label);
    }
    for want in ["implicit (faer), q4 x1", "explicit local, qm6 x2", "Pareto front", "wall time (s)", "relative error vs analytic (dimensionless)"] {
        assert!(all.contains(&want), "{want:?} missing from {all:?}");
    }
    // Wall times 1e-3 .. 3 s and errors 1e-4 .. 0.2: labels at the decades inside, nothing else.
    let mut got: Vec<&str> = ticks(&t).iter().map(|t| t.s.as_str()).collect();
    got.sort();
    let mut want = vec!["0.001", "0.01", "0.1", "1", "1e-4", "1e-3", "1e-2", "1e-1"];
    want.sort();
    assert_eq!(got, want);
    assert_no_overlap(&ticks(&t));
    std::fs::remove_dir_all(&d).unwrap();
}

/// Every point with the same error (the crack path chart of issue 40): one tick at that value,
/// labelled, and a note saying so; the same for all errors 0.
#[test]
fn speed_accuracy_axis_without_range_gets_a_tick_and_a_note() {
    let d = tmp("flat");
    for (err, tick) in [(0.05, "0.05"), (0.0, "0")] {
        let pts: Vec<ChartPoint> = (0..5).map(|k| pt(if k == 0 { "events (ours)" } else { "explicit" }, "", if k == 0 { "" } else { "tolerance 1e-4" }, 0.5 * (k + 1) as f64, err, k == 0)).collect();
        speed_accuracy(&d.join("flat"), "flat", "share of split edges differing (dimensionless)", &pts).unwrap();
        let t = texts(&std::fs::read_to_string(d.join("flat.svg")).unwrap());
        let all: Vec<&str> = t.iter().map(|t| t.s.as_str()).collect();
        assert!(all.contains(&tick), "tick {tick:?} missing: {all:?}");
        let notes = all.iter().filter(|s| s.starts_with("note:")).collect::<Vec<_>>().len();
        assert!(notes >= 1 && all.join(" ").contains(&format!("every point has error {tick}")), "no note: {all:?}");
        // y ticks: that one value only (the x axis, 0.5..2.5 s, labels 1-2-5).
        let bottom = ticks(&t).iter().map(|x| x.y).fold(0.0f64, f64::max);
        let y_ticks: Vec<&str> = ticks(&t).iter().filter(|x| x.y < bottom - 1.0).map(|x| x.s.as_str()).collect();
        assert_eq!(y_ticks, vec![tick]);
        let x_ticks: Vec<&str> = ticks(&t).iter().filter(|x| x.y >= bottom - 1.0).map(|x| x.s.as_str()).collect();
        assert_eq!(x_ticks, vec!["0.5", "1", "2"]);
        assert!(all.contains(&"events (ours)") && all.contains(&"explicit, tolerance 1e-4"), "{all:?}");
        assert_no_overlap(&ticks(&t));
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Log axes over many decades label at most nine of them; some values 0 among positive ones are
/// drawn on a line labelled "0", a decade below the rest; less than a decade gets 1-2-5.
#[test]
fn log_axes_label_decades_or_125_only() {
    let a = log_axis(&[1e-14, 3e-2, 0.1], "error");
    assert!(a.bold.len() <= 9 && a.bold.len() >= 5, "{:?}", a.bold);
    for b in &a.bold {
        let m = b / 10f64.powf(b.log10().floor());
        assert!((m - 1.0).abs() < 1e-9, "not a decade: {b}");
    }
    let z = log_axis(&[0.0, 2e-3, 4e-2], "error");
    assert_eq!(z.zero, Some(1e-4));
    assert_eq!(z.label(1e-4), "0");
    assert_eq!(z.bold[0], 1e-4);
    assert_eq!(z.bold, vec![1e-4, 1e-3, 1e-2]);
    assert!(z.light.iter().all(|v| *v > 0.999e-3), "no grid line between the zero line and the data: {:?}", z.light);
    assert!(z.notes[0].contains("1 point(s) with error 0"), "{:?}", z.notes);
    let n = log_axis(&[2.0, 3.5], "wall time (s)");
    let labels: Vec<String> = n.bold.iter().map(|v| n.label(*v)).collect();
    assert_eq!(labels, vec!["2", "5"]);
}

/// More meshes than marker shapes is an error naming them, never two series drawn alike.
#[test]
fn series_styles_refuse_what_they_cannot_tell_apart() {
    let pts: Vec<ChartPoint> = (0..6).map(|k| pt("explicit adaptive", "", &format!("x{}", 1 << k), 1.0, 0.1, false)).collect();
    let e = series_styles(&pts).unwrap_err().to_string();
    assert!(e.contains("6 meshes") && e.contains("x32"), "{e}");
}

#[test]
fn stability_and_converge_charts_name_their_units() {
    let d = tmp("stab");
    let data = StabilityData {
        thresholds: vec![("q4 square".into(), 0.99), ("contact".into(), 1.02)],
        damping: vec![
            ("local".into(), 0.01, 9e4, true),
            ("local".into(), 0.1, 8e3, true),
            ("local".into(), 0.8, 400.0, true),
            ("viscous".into(), 0.05, 2e4, true),
            ("viscous".into(), 1.0, 3e3, false),
        ],
    };
    flem_plot::charts::stability(&d.join("stability"), &data).unwrap();
    let t = texts(&std::fs::read_to_string(d.join("stability.svg")).unwrap());
    let all: Vec<&str> = t.iter().map(|t| t.s.as_str()).collect();
    for want in ["local", "viscous", "steps to rest (count)", "q4 square"] {
        assert!(all.contains(&want), "{want:?} missing: {all:?}");
    }
    assert!(all.iter().any(|s| s.starts_with("damping parameter (dimensionless")), "{all:?}");
    assert!(all.iter().any(|s| s.starts_with("measured threshold / prediction (dimensionless")), "{all:?}");
    // Steps 400 .. 9e4: decades 1e3, 1e4 (plain would mix 1000 with 1e5: one style).
    let log_ticks: Vec<&str> = ticks(&t).iter().filter(|x| x.s.contains('e')).map(|x| x.s.as_str()).collect();
    assert!(log_ticks.contains(&"1e3") && log_ticks.contains(&"1e4"), "{log_ticks:?}");
    assert_no_overlap(&ticks(&t));
    let lv =
        vec![ConvergeLevel { h: 0.5, p_local: Some(1.1), p_nonlocal: Some(1.0), path: vec![[0.5, 0.5]] }, ConvergeLevel { h: 0.25, p_local: Some(0.9), p_nonlocal: Some(1.0), path: vec![[0.5, 0.6]] }];
    flem_plot::charts::converge(&d.join("converge"), "converge", &lv, [[0.0, 0.0], [1.0, 1.0]]).unwrap();
    let t = texts(&std::fs::read_to_string(d.join("converge.svg")).unwrap());
    let all: Vec<&str> = t.iter().map(|t| t.s.as_str()).collect();
    for want in
        ["element size h, mean edge (length units of the scene)", "initiation load factor p_crit (dimensionless)", "x (length units of the scene)", "local (paper: corner mean)", "nonlocal (ours)"]
    {
        assert!(all.contains(&want), "{want:?} missing: {all:?}");
    }
    std::fs::remove_dir_all(&d).unwrap();
}
