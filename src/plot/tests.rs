//! Figures against their data: ranges, files, robustness.

use std::fs;

use super::*;

/// Fresh output directory for one test.
fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir()
        .join("cable-servo-plot-tests")
        .join(name);
    let _ = fs::remove_dir_all(&dir);
    dir
}

/// Files exist, are non-empty, PNG is a PNG of the expected size, SVG is
/// an SVG, and no temporary file is left behind.
fn check_outputs(paths: &[PathBuf], size: (u32, u32)) {
    assert_eq!(paths.len(), 2);
    let png = fs::read(&paths[0]).expect("png readable");
    assert!(paths[0].extension().is_some_and(|e| e == "png"));
    assert!(png.len() > 1000, "png too small: {}", png.len());
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let w = u32::from_be_bytes([png[16], png[17], png[18], png[19]]);
    let h = u32::from_be_bytes([png[20], png[21], png[22], png[23]]);
    assert_eq!((w, h), size);
    let svg = fs::read_to_string(&paths[1]).expect("svg readable");
    assert!(paths[1].extension().is_some_and(|e| e == "svg"));
    assert!(svg.contains("<svg"));
    assert!(svg.trim_end().ends_with("</svg>"));
    let dir = paths[0].parent().expect("parent");
    for entry in fs::read_dir(dir).expect("dir") {
        let name = entry.expect("entry").file_name();
        assert!(
            !name.to_string_lossy().ends_with(".tmp"),
            "temporary file left: {name:?}"
        );
    }
}

fn is_sorted(v: &[f64]) -> bool {
    v.windows(2).all(|w| w[0] <= w[1])
}

#[test]
fn decimate_keeps_extremes_and_bounds() {
    let n = 100_000;
    let x: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let mut y: Vec<f64> = x.iter().map(|t| (t * 7.0).sin()).collect();
    y[12_345] = 5.0; // single-sample spike
    y[77_777] = -4.0;
    for buckets in [1, 7, 100, 1000] {
        let (dx, dy) = decimate_minmax(&x, &y, buckets);
        assert!(dx.len() <= 2 * buckets, "{} > 2*{buckets}", dx.len());
        assert_eq!(dx.len(), dy.len());
        assert!(dy.contains(&5.0) && dy.contains(&-4.0));
        assert!(is_sorted(&dx));
        // Every output point is an input point.
        for (xx, yy) in dx.iter().zip(&dy) {
            let i = (xx * 1e3).round() as usize;
            assert_eq!(y[i], *yy);
        }
    }
    // buckets == 0 behaves like 1.
    let (dx, _) = decimate_minmax(&x, &y, 0);
    assert!(dx.len() <= 2);
}

#[test]
fn decimate_short_and_edge_cases() {
    assert_eq!(decimate_minmax(&[], &[], 10), (vec![], vec![]));
    assert_eq!(decimate_minmax(&[1.0], &[2.0], 10), (vec![1.0], vec![2.0]));
    assert_eq!(decimate_minmax(&[1.0], &[2.0], 0), (vec![1.0], vec![2.0]));
    // Short series (even with NaN) are returned unchanged.
    let (dx, dy) = decimate_minmax(&[0.0, 1.0, 2.0], &[1.0, f64::NAN, 3.0], 2);
    assert_eq!(dx, vec![0.0, 1.0, 2.0]);
    assert!(dy[1].is_nan());
    // Mismatched lengths use the common prefix.
    let (dx, dy) = decimate_minmax(&[0.0, 1.0, 2.0], &[5.0, 6.0], 10);
    assert_eq!((dx.len(), dy.len()), (2, 2));
}

#[test]
fn decimate_handles_nan() {
    let n = 50_000;
    let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let mut y: Vec<f64> = x.iter().map(|t| (t * 0.01).cos()).collect();
    for i in (0..n).step_by(97) {
        y[i] = f64::NAN;
    }
    y[5] = f64::INFINITY;
    y[40_000] = 9.0;
    y[40_001] = -9.0;
    let mut x2 = x.clone();
    x2[100] = f64::NAN;
    let (dx, dy) = decimate_minmax(&x2, &y, 50);
    assert!(dx.len() <= 100);
    assert!(dx.iter().chain(&dy).all(|v| v.is_finite()));
    assert!(dy.contains(&9.0) && dy.contains(&-9.0));
    assert!(is_sorted(&dx));
    // Only non-finite data reduces to nothing, without panicking.
    let nan = vec![f64::NAN; 1000];
    assert_eq!(decimate_minmax(&nan, &nan, 10), (vec![], vec![]));
    // Constant x (zero width: falls back to equal-count buckets).
    let cx = vec![1.0; 1000];
    let (dx, dy) = decimate_minmax(&cx, &y[..1000], 10);
    assert!(dx.len() <= 20 && !dy.is_empty());
}

#[test]
fn decimate_non_monotonic_x() {
    // A hysteresis-like loop: x goes up and down.
    let n = 20_000;
    let t: Vec<f64> = (0..n)
        .map(|i| i as f64 / n as f64 * std::f64::consts::TAU)
        .collect();
    let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
    let y: Vec<f64> = t.iter().map(|t| (t + 0.5).sin()).collect();
    let (dx, dy) = decimate_minmax(&x, &y, 100);
    assert!(dx.len() <= 200 && dx.len() == dy.len());
    let ymax = y.iter().copied().fold(f64::MIN, f64::max);
    let ymin = y.iter().copied().fold(f64::MAX, f64::min);
    assert!(dy.contains(&ymax) && dy.contains(&ymin));
}

#[test]
fn ticks_and_labels_are_clean() {
    let a = Axis::linear(0.0, 0.7, 8);
    let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
    assert_eq!(
        labels,
        ["0.0", "0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
    );
    let a = Axis::linear(-3.3, 12.0, 8);
    let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
    assert_eq!(labels, ["-2", "0", "2", "4", "6", "8", "10", "12"]);
    let a = Axis::linear(-2e-6, 3e-6, 6);
    assert!(a.major.len() >= 3);
    assert!(a.major.iter().all(|&v| !a.label(v).is_empty()));
    let lg = Axis::log10(-1.0, 3.0);
    let labels: Vec<String> = lg.major.iter().map(|&v| lg.label(v)).collect();
    for want in ["0.1", "1", "10", "100", "1000"] {
        assert!(labels.contains(&want.to_string()), "{labels:?}");
    }
    let lg = Axis::log10(2.0, 8.0);
    let labels: Vec<String> = lg.major.iter().map(|&v| lg.label(v)).collect();
    assert!(labels.contains(&"1e6".to_string()), "{labels:?}");
    // Narrow log range still gets at least two ticks.
    assert!(Axis::log10(0.0, 0.05).major.len() >= 2);
    let a = Axis::linear(0.9e6, 1.7e6, 4);
    let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
    assert_eq!(labels, ["1.0e6", "1.2e6", "1.4e6", "1.6e6"]);
    let a = Axis::linear(-f64::MAX, f64::MAX, 8);
    let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
    assert!(labels.contains(&"1.5e308".to_string()), "{labels:?}");
    assert_eq!(fmt_log_tick(-240.0), "1e-240");
    assert_eq!(fmt_log_tick(60.0 + 2f64.log10()), "2e60");
    assert_eq!(fmt_log_tick(-2.0 + 5f64.log10()), "0.05");
    assert_eq!(fmt_log_tick(6.0 - 1e-12), "1e6");
    assert_eq!(fmt_general(0.002), "0.002");
    assert_eq!(fmt_general(2e-5), "2e-5");
}

#[test]
fn ranges_are_never_degenerate() {
    let (a, b) = auto_range(3.0, 3.0, false);
    assert!(b > a && a < 3.0 && b > 3.0);
    let (a, b) = auto_range(0.0, 0.0, false);
    assert!(b > a);
    let (a, b) = auto_range(f64::INFINITY, f64::NEG_INFINITY, false);
    assert!(b > a);
    let (a, b) = explicit_range((2.0, 2.0), false, "y").expect("padded");
    assert!(b > a);
    let (a, b) = explicit_range((5.0, 1.0), false, "y").expect("swapped");
    assert_eq!((a, b), (1.0, 5.0));
    assert!(explicit_range((f64::NAN, 1.0), false, "y").is_err());
    assert!(explicit_range((0.0, 10.0), true, "x").is_err());
}

#[test]
fn zoomed_long_trace_keeps_resolution() {
    // 200k samples over 0..100 s, viewing only 1..2 s: the visible second
    // still gets about one bucket per pixel, and two series don't share it.
    let n = 200_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 5e-4).collect();
    let y: Vec<f64> = t.iter().map(|t| (t * 50.0).sin()).collect();
    let chart = Chart {
        series: vec![
            Series::line("a", t.clone(), y.clone()),
            Series::step("b", t.clone(), y.clone()),
        ],
        x_range: Some((1.0, 2.0)),
        ..Default::default()
    };
    let buckets = plot_buckets(CHART_SIZE.0);
    let p = prepare_chart(&chart, buckets).expect("prepare");
    let a: usize = p.series[0].lines.iter().map(Vec::len).sum();
    assert!(a >= buckets, "only {a} points for {buckets} buckets");
    assert!(a <= 2 * buckets + 4, "{a}");
    for l in p.series.iter().flat_map(|s| &s.lines) {
        assert!(l.iter().all(|q| (1.0..=2.0).contains(&q.0)));
    }
    // A segment crossing the whole view with both ends outside is kept.
    let kept = trim_to_x(&[0.0, 10.0], &[1.0, 2.0], 4.0, 5.0);
    assert_eq!(kept.len(), 1);
    assert_eq!(kept[0].0, vec![0.0, 10.0]);
    assert!(trim_to_x(&[0.0, 1.0], &[1.0, 2.0], 4.0, 5.0).is_empty());
}

#[test]
fn clipping_splits_and_rejoins() {
    let b = Bounds {
        x0: 0.0,
        x1: 10.0,
        y0: 0.0,
        y1: 1.0,
    };
    let pts = vec![(0.0, 0.5), (2.0, 0.5), (3.0, 2.0), (4.0, 0.5), (6.0, 0.5)];
    let lines = clip_polyline(&pts, &b);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert_eq!(lines[0][0], (0.0, 0.5));
    assert_eq!(lines[1].last(), Some(&(6.0, 0.5)));
    for l in &lines {
        for p in l {
            assert!(b.contains(*p), "{p:?} outside");
        }
    }
    assert!(clip_segment((-1.0, 5.0), (11.0, 5.0), &b).is_none());
}

#[test]
fn contour_segments_are_chained() {
    // An L-shaped edge path plus a separate segment.
    let segs = vec![
        ((1.0, 0.0), (1.0, 1.0)),
        ((2.0, 5.0), (3.0, 5.0)),
        ((1.0, 1.0), (2.0, 1.0)),
        ((0.0, 0.0), (1.0, 0.0)),
        ((2.0, 1.0), (3.0, 1.0)), // collinear continuation
    ];
    let mut lines = chain_segments(&segs);
    lines.sort_by_key(|l| l.len());
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0].len(), 2);
    assert_eq!(lines[1].len(), 4, "{lines:?}");
    let ends = [lines[1][0], lines[1][3]];
    assert!(ends.contains(&(0.0, 0.0)) && ends.contains(&(3.0, 1.0)));
}

#[test]
fn save_chart_messy_data() {
    let dir = out_dir("messy");
    let t: Vec<f64> = (0..500).map(|i| i as f64 * 0.01).collect();
    let mut err: Vec<f64> = t
        .iter()
        .map(|t| 0.15 * (-t).exp() * (t * 9.0).sin())
        .collect();
    err[100] = f64::NAN;
    err[200] = f64::INFINITY;
    err[201] = f64::NEG_INFINITY;
    let mut t2 = t.clone();
    t2[300] = f64::NAN;
    let chart = Chart {
        title: "Pointing error (messy data)".into(),
        x_label: "time [s]".into(),
        y_label: "error [mrad]".into(),
        series: vec![
            Series::line("az error", t2.clone(), err.clone()),
            Series::line("empty", vec![], vec![]),
            Series::line("constant", t.clone(), vec![0.05; t.len()]),
            Series::step(
                "command (ZOH)",
                t.iter().step_by(50).copied().collect(),
                err.iter().step_by(50).map(|v| v * 0.5).collect(),
            ),
            Series::points(
                "samples",
                t.iter().step_by(25).copied().collect(),
                vec![-0.1; 20],
            ),
            Series::line("all nan", vec![f64::NAN; 3], vec![1.0; 3]),
            Series::line("", vec![1.0, 2.0], vec![f64::NAN, 0.0]),
        ],
        bands: vec![
            HBand {
                lo: -0.1,
                hi: 0.1,
                label: "target ±0.1 mrad".into(),
            },
            HBand {
                lo: f64::NAN,
                hi: 1.0,
                label: "invisible".into(),
            },
        ],
        ..Default::default()
    };
    let paths = save_chart(&chart, &dir.join("messy")).expect("save");
    check_outputs(&paths, CHART_SIZE);
    let svg = fs::read_to_string(&paths[1]).expect("svg");
    assert!(svg.contains("target ±0.1 mrad"));
    assert!(svg.contains("az error"));
    assert!(
        !svg.contains("all nan"),
        "all-NaN series must not be in legend"
    );
    assert!(!svg.contains("invisible"));
    assert!(!svg.contains("NaN"));
}

#[test]
fn save_chart_degenerate_and_empty() {
    let dir = out_dir("degenerate");
    // Only a constant series (single point, even).
    let chart = Chart {
        series: vec![Series::line("c", vec![1.0], vec![2.0])],
        ..Default::default()
    };
    check_outputs(
        &save_chart(&chart, &dir.join("single")).expect("single"),
        CHART_SIZE,
    );
    // No finite data at all.
    let chart = Chart {
        title: "nothing".into(),
        series: vec![
            Series::line("nan", vec![f64::NAN; 4], vec![f64::NAN; 4]),
            Series::points("empty", vec![], vec![]),
        ],
        ..Default::default()
    };
    let paths = save_chart(&chart, &dir.join("empty")).expect("empty");
    check_outputs(&paths, CHART_SIZE);
    assert!(fs::read_to_string(&paths[1])
        .expect("svg")
        .contains("no finite data"));
    // Completely default chart.
    check_outputs(
        &save_chart(&Chart::default(), &dir.join("default")).expect("default"),
        CHART_SIZE,
    );
    // Explicit ranges clip the data; dotted stem keeps its dot.
    let chart = Chart {
        series: vec![Series::line(
            "clipped",
            (0..100).map(f64::from).collect(),
            (0..100).map(|i| f64::from(i) * 10.0).collect(),
        )],
        x_range: Some((90.0, 10.0)),
        y_range: Some((100.0, 100.0)),
        ..Default::default()
    };
    let paths = save_chart(&chart, &dir.join("run_0.1")).expect("ranges");
    assert_eq!(paths[0].file_name().expect("name"), "run_0.1.png");
    check_outputs(&paths, CHART_SIZE);
}

#[test]
fn failed_write_leaves_no_temporary_files() {
    let dir = out_dir("blocked");
    // A directory where the PNG should go makes the final rename fail.
    fs::create_dir_all(dir.join("fig.png").join("occupied")).expect("mkdir");
    let chart = Chart {
        series: vec![Series::line("a", vec![0.0, 1.0], vec![0.0, 1.0])],
        ..Default::default()
    };
    let res = save_chart(&chart, &dir.join("fig"));
    assert!(matches!(res, Err(PlotError::Io { .. })), "{res:?}");
    assert!(!dir.join("fig.png.tmp").exists());
    assert!(!dir.join("fig.svg.tmp").exists());
    // A stale temporary from a crashed run does not block a new save.
    fs::create_dir_all(dir.join("ok.png.tmp").join("junk")).expect("mkdir");
    fs::write(dir.join("ok.svg.tmp"), b"half-written").expect("write");
    let paths = save_chart(&chart, &dir.join("ok")).expect("save over stale tmp");
    assert!(!dir.join("ok.png.tmp").exists() && !dir.join("ok.svg.tmp").exists());
    assert!(paths.iter().all(|p| p.exists()));
}

#[test]
fn save_chart_extreme_values() {
    let dir = out_dir("extreme");
    let big = f64::MAX;
    let chart = Chart {
        series: vec![
            Series::line("huge", vec![-big, 0.0, big], vec![big, -big, 1e-320]),
            Series::points("tiny", vec![1e-310, 2e-310], vec![5e-324, 0.0]),
        ],
        bands: vec![HBand {
            lo: f64::NEG_INFINITY,
            hi: f64::INFINITY,
            label: "everything".into(),
        }],
        ..Default::default()
    };
    check_outputs(
        &save_chart(&chart, &dir.join("huge")).expect("huge"),
        CHART_SIZE,
    );
    let chart = Chart {
        series: vec![Series::step(
            "tiny",
            vec![0.0, 1e-300, 2e-300],
            vec![1.0, 1.0 + 1e-15, 1.0],
        )],
        log_x: true,
        x_range: Some((1e-300, 1e300)),
        ..Default::default()
    };
    check_outputs(
        &save_chart(&chart, &dir.join("wide_log")).expect("wide"),
        CHART_SIZE,
    );
    let map = Heatmap {
        title: String::new(),
        x_label: String::new(),
        y_label: String::new(),
        z_label: String::new(),
        x: vec![0.0, 1.0],
        y: vec![0.0, 1.0],
        z: vec![vec![big, -big], vec![f64::INFINITY, 0.0]],
        contour: Some(0.5),
        log_x: false,
        log_y: false,
        log_z: false,
    };
    check_outputs(
        &save_heatmap(&map, &dir.join("heat")).expect("heat"),
        HEATMAP_SIZE,
    );
}

#[test]
fn save_chart_log_x() {
    let dir = out_dir("log");
    let f: Vec<f64> = (-20..=60)
        .map(|i| 10f64.powf(f64::from(i) / 20.0))
        .collect();
    let mag: Vec<f64> = f
        .iter()
        .map(|f| -20.0 * (1.0 + (f / 30.0).powi(2)).sqrt().log10())
        .collect();
    let mut fx = f.clone();
    fx[0] = 0.0;
    fx[1] = -5.0;
    let chart = Chart {
        title: "Closed-loop response".into(),
        x_label: "frequency [Hz]".into(),
        y_label: "magnitude [dB]".into(),
        series: vec![
            Series::line("|T(jω)|", fx.clone(), mag.clone()),
            Series::points(
                "measured",
                fx.iter().step_by(7).copied().collect(),
                mag.iter().step_by(7).map(|m| m + 0.5).collect(),
            ),
            Series::line("non-positive only", vec![0.0, -1.0], vec![1.0, 2.0]),
        ],
        bands: vec![HBand {
            lo: -3.0,
            hi: f64::INFINITY,
            label: "-3 dB".into(),
        }],
        log_x: true,
        ..Default::default()
    };
    check_outputs(
        &save_chart(&chart, &dir.join("bode")).expect("log"),
        CHART_SIZE,
    );
    // Invalid explicit log range is an error and leaves no files.
    let bad = Chart {
        log_x: true,
        x_range: Some((0.0, 10.0)),
        ..chart.clone()
    };
    assert!(matches!(
        save_chart(&bad, &dir.join("bad")),
        Err(PlotError::InvalidInput(_))
    ));
    assert!(!dir.join("bad.png").exists() && !dir.join("bad.svg").exists());
    // Log axis with only non-positive x: empty figure, no panic.
    let none = Chart {
        series: vec![Series::line("neg", vec![-1.0, 0.0], vec![1.0, 2.0])],
        log_x: true,
        ..Default::default()
    };
    check_outputs(
        &save_chart(&none, &dir.join("none")).expect("none"),
        CHART_SIZE,
    );
}

#[test]
fn save_heatmap_nan_and_contour() {
    let dir = out_dir("heat");
    let x: Vec<f64> = (0..30).map(|i| 0.5 + f64::from(i) * 0.1).collect();
    let y: Vec<f64> = (0..20).map(|i| 100.0 + f64::from(i) * 25.0).collect();
    let z: Vec<Vec<f64>> = y
        .iter()
        .enumerate()
        .map(|(iy, yv)| {
            x.iter()
                .enumerate()
                .map(|(ix, xv)| {
                    if (ix + iy) % 17 == 0 || (iy > 15 && ix > 25) {
                        f64::NAN
                    } else {
                        0.02 + 0.3 * (xv - 1.5).powi(2) + yv / 5000.0
                    }
                })
                .collect()
        })
        .collect();
    let map = Heatmap {
        title: "Pointing error over preload and stiffness".into(),
        x_label: "preload [N]".into(),
        y_label: "stiffness [N/mm]".into(),
        z_label: "RMS error [mrad]".into(),
        x,
        y,
        z,
        contour: Some(0.1),
        log_x: false,
        log_y: false,
        log_z: false,
    };
    let prepared = prepare_heatmap(&map).expect("prepare");
    assert!(prepared.has_missing);
    assert!(!prepared.contour.as_ref().expect("contour").1.is_empty());
    let paths = save_heatmap(&map, &dir.join("sweep")).expect("heatmap");
    check_outputs(&paths, HEATMAP_SIZE);
    let svg = fs::read_to_string(&paths[1]).expect("svg");
    assert!(svg.contains("failed or stopped case") && svg.contains("target 0.1 mrad"));

    // All-NaN and single-cell maps still render.
    let single = Heatmap {
        x: vec![1.0],
        y: vec![2.0],
        z: vec![vec![f64::NAN]],
        contour: None,
        ..map.clone()
    };
    check_outputs(
        &save_heatmap(&single, &dir.join("single")).expect("single"),
        HEATMAP_SIZE,
    );
    // Bad dimensions are errors.
    let bad = Heatmap {
        z: vec![vec![1.0; 3]],
        ..map.clone()
    };
    assert!(matches!(
        save_heatmap(&bad, &dir.join("bad")),
        Err(PlotError::InvalidInput(_))
    ));
    let bad = Heatmap { x: vec![], ..map };
    assert!(save_heatmap(&bad, &dir.join("bad")).is_err());
}

/// A log-spaced sweep variable on a log axis: every cell equally wide, its centre in the
/// middle (edges at geometric means), the axis logarithmic; a value that is not positive
/// is refused.
#[test]
fn heatmap_log_axes_centre_log_spaced_cells() {
    let dir = out_dir("heatmap_log");
    let x: Vec<f64> = vec![1.0, 10.0, 100.0, 1000.0];
    let y = vec![5.0, 50.0, 500.0];
    let z: Vec<Vec<f64>> = y
        .iter()
        .map(|yv| x.iter().map(|xv| (xv * yv).log10()).collect())
        .collect();
    let map = Heatmap {
        title: "log axes".into(),
        x_label: "kp".into(),
        y_label: "ki".into(),
        z_label: "rms_mrad".into(),
        x,
        y,
        z,
        contour: Some(2.0),
        log_x: true,
        log_y: true,
        log_z: false,
    };
    let p = prepare_heatmap(&map).expect("prepared");
    assert!(p.x.log && p.y.log);
    for (i, (a, b, _)) in p.cells.iter().take(4).enumerate() {
        assert!(
            (b.0 - a.0 - 1.0).abs() < 1e-12,
            "cell {i} is {} decades",
            b.0 - a.0
        );
        assert!(
            (0.5 * (a.0 + b.0) - i as f64).abs() < 1e-12,
            "cell {i} off centre"
        );
    }
    check_outputs(
        &save_heatmap(&map, &dir.join("log")).expect("drawn"),
        HEATMAP_SIZE,
    );
    let linear = prepare_heatmap(&Heatmap {
        log_x: false,
        log_y: false,
        ..map.clone()
    })
    .expect("prepared");
    assert!((linear.cells[1].1 .0 - linear.cells[1].0 .0 - 49.5).abs() < 1e-9);
    let bad = Heatmap {
        x: vec![0.0, 10.0, 100.0, 1000.0],
        ..map
    };
    match prepare_heatmap(&bad) {
        Err(PlotError::InvalidInput(m)) => assert!(m.contains("not positive"), "{m}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn save_panels_three_charts() {
    let dir = out_dir("panels");
    let t: Vec<f64> = (0..2000).map(|i| f64::from(i) * 1e-3).collect();
    let angle = |f: f64| t.iter().map(|t| (t * f).sin()).collect::<Vec<_>>();
    let charts = vec![
        Chart {
            title: "Gimbal angles".into(),
            y_label: "angle [deg]".into(),
            series: vec![
                Series::line("azimuth", t.clone(), angle(3.0)),
                Series::line("elevation", t.clone(), angle(5.0)),
            ],
            ..Default::default()
        },
        Chart {
            title: "Pointing error".into(),
            y_label: "error [mrad]".into(),
            series: vec![Series::line(
                "error",
                t.clone(),
                t.iter()
                    .map(|t| 0.3 * (-3.0 * t).exp() * (t * 40.0).sin())
                    .collect(),
            )],
            bands: vec![HBand {
                lo: -0.1,
                hi: 0.1,
                label: "target".into(),
            }],
            ..Default::default()
        },
        Chart {
            title: "Cable tensions".into(),
            x_label: "time [s]".into(),
            y_label: "tension [N]".into(),
            series: vec![
                Series::step(
                    "T1",
                    t.clone(),
                    t.iter().map(|t| 120.0 + 30.0 * (t * 3.0).sin()).collect(),
                ),
                Series::step(
                    "T2",
                    t.clone(),
                    t.iter().map(|t| 120.0 - 30.0 * (t * 3.0).sin()).collect(),
                ),
            ],
            ..Default::default()
        },
    ];
    let paths = save_panels(
        "Step response, 10 deg",
        &charts,
        &dir.join("nested/dir/step"),
    )
    .expect("panels");
    check_outputs(&paths, (PANEL_WIDTH, 50 + 3 * PANEL_HEIGHT));
    assert!(matches!(
        save_panels("x", &[], &dir.join("none")),
        Err(PlotError::InvalidInput(_))
    ));
    let many = vec![Chart::default(); MAX_PANELS + 1];
    assert!(matches!(
        save_panels("x", &many, &dir.join("many")),
        Err(PlotError::InvalidInput(_))
    ));
}

#[test]
fn save_chart_200k_points() {
    let dir = out_dir("big");
    let n = 200_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let y: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, t)| (t * 2.0).sin() + if i == 123_456 { 3.0 } else { 0.0 })
        .collect();
    let chart = Chart {
        title: "200k samples".into(),
        x_label: "time [s]".into(),
        y_label: "signal".into(),
        series: vec![
            Series::line("trace", t.clone(), y.clone()),
            Series::step("held", t.clone(), y.iter().map(|v| v * 0.5).collect()),
        ],
        ..Default::default()
    };
    let prepared = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepare");
    let drawn: usize = prepared.series[0].lines.iter().map(Vec::len).sum();
    assert!(drawn <= 2 * plot_buckets(CHART_SIZE.0) + 2, "{drawn}");
    let peak = prepared.series[0].lines.iter().flatten().any(|p| p.1 > 2.5);
    assert!(peak, "spike lost by decimation");
    let paths = save_chart(&chart, &dir.join("big")).expect("save");
    check_outputs(&paths, CHART_SIZE);
}

/// The chart rasterised in memory as the PNG is (RGB, row by row).
fn raster(chart: &Chart) -> (Vec<u8>, u32) {
    output::ensure_fonts().expect("fonts");
    let fig =
        chart::SingleFigure(prepare_chart(chart, plot_buckets(CHART_SIZE.0)).expect("prepared"));
    let (w, h) = fig.size();
    let mut buf = vec![0u8; (w * h * 3) as usize];
    output::draw(
        &fig,
        plotters::prelude::BitMapBackend::with_buffer(&mut buf, (w, h)),
        Path::new("memory"),
    )
    .expect("drawn");
    (buf, w)
}

/// Rows (top, bottom) of the pixels where two rasters differ.
fn changed_rows(a: &[u8], b: &[u8], width: u32) -> (usize, usize) {
    let row_bytes = width as usize * 3;
    let rows: Vec<usize> = a
        .chunks(row_bytes)
        .zip(b.chunks(row_bytes))
        .enumerate()
        .filter(|(_, (ra, rb))| ra != rb)
        .map(|(i, _)| i)
        .collect();
    (
        rows.first().copied().unwrap_or(0),
        rows.last().copied().unwrap_or(0),
    )
}

/// A long trace with sharp steps and noise, drawn as a bitmap, stays within the rows of
/// its own data range (one pixel of tolerance): the bitmap shows no spike the data lacks.
#[test]
fn bitmap_trace_stays_within_its_data_range() {
    let n = 200_000;
    let x: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let y: Vec<f64> = (0..n)
        .map(|i| {
            let level = if (i / 25_000) % 2 == 0 { 0.21 } else { -0.22 };
            level + 0.004 * ((i as f64 * 0.37).sin() + (i as f64 * 1.91).cos())
        })
        .collect();
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let chart = |series: Vec<Series>| Chart {
        title: "raster".into(),
        x_label: "t [s]".into(),
        y_label: "e [mrad]".into(),
        series,
        x_range: Some((0.0, 20.0)),
        y_range: Some((-0.5, 0.5)),
        ..Chart::default()
    };
    let (base, w) = raster(&chart(vec![Series::line("", vec![], vec![])]));
    let (trace, _) = raster(&chart(vec![Series::line("", x.clone(), y)]));
    let (bounds, _) = raster(&chart(vec![
        Series::line("", vec![0.0, 20.0], vec![hi, hi]),
        Series::line("", vec![0.0, 20.0], vec![lo, lo]),
    ]));
    let (trace_top, trace_bottom) = changed_rows(&base, &trace, w);
    let (bound_top, bound_bottom) = changed_rows(&base, &bounds, w);
    assert!(trace_bottom > trace_top, "nothing drawn");
    assert!(
        trace_top + 1 >= bound_top && trace_bottom <= bound_bottom + 1,
        "trace rows {trace_top}..{trace_bottom}, data rows {bound_top}..{bound_bottom}"
    );
}

/// Any figure rasterised in memory as the PNG is (RGB, row by row).
fn raster_figure<F: Figure>(fig: &F) -> (Vec<u8>, u32) {
    output::ensure_fonts().expect("fonts");
    let (w, h) = fig.size();
    let mut buf = vec![0u8; (w * h * 3) as usize];
    output::draw(
        fig,
        plotters::prelude::BitMapBackend::with_buffer(&mut buf, (w, h)),
        Path::new("memory"),
    )
    .expect("drawn");
    (buf, w)
}

/// Rows where two rasters differ.
fn rows_changed(a: &[u8], b: &[u8], width: u32) -> Vec<usize> {
    let row_bytes = width as usize * 3;
    a.chunks(row_bytes)
        .zip(b.chunks(row_bytes))
        .enumerate()
        .filter(|(_, (ra, rb))| ra != rb)
        .map(|(i, _)| i)
        .collect()
}

/// Data that runs far outside a fixed axis, with a legend and bands: every pixel the
/// data, the bands or the legend change lies below the title's last row, in a single
/// chart and in each panel of a panel figure (under the shared title and the panel's own).
#[test]
fn nothing_drawn_over_a_title() {
    let x: Vec<f64> = (0..5000).map(|i| i as f64 * 1e-3).collect();
    let wild: Vec<f64> = x
        .iter()
        .map(|t| 40.0 * (t * 9.0).sin() + if (t * 10.0) as i64 % 7 == 0 { 1e6 } else { 0.0 })
        .collect();
    let chart = |title: &str, data: bool| Chart {
        title: title.into(),
        x_label: "time [s]".into(),
        y_label: "tension [N]".into(),
        series: if data {
            vec![
                Series::line("upper span, a long legend label", x.clone(), wild.clone()),
                Series::line("lower span", x.clone(), wild.iter().map(|v| -v).collect()),
            ]
        } else {
            vec![Series::line("", vec![], vec![])]
        },
        bands: if data {
            vec![HBand {
                lo: -1e9,
                hi: 1e9,
                label: "band wider than the axis".into(),
            }]
        } else {
            vec![]
        },
        y_range: Some((-1.0, 1.0)),
        ..Chart::default()
    };
    let title = "Span tensions, a title as long as a design review's figure titles get";
    let single = |c: Chart| {
        chart::SingleFigure(prepare_chart(&c, plot_buckets(CHART_SIZE.0)).expect("prepared"))
    };
    // The title's rows: where the figure changes when only the title's text does (the
    // same letters reversed lay out to the same height, so nothing else moves).
    let reversed: String = title.chars().rev().collect();
    let (titled, w) = raster_figure(&single(chart(title, false)));
    let (other, _) = raster_figure(&single(chart(&reversed, false)));
    let (full, _) = raster_figure(&single(chart(title, true)));
    let title_last = *rows_changed(&titled, &other, w)
        .last()
        .expect("the title is drawn");
    let data_first = *rows_changed(&titled, &full, w)
        .first()
        .expect("the data is drawn");
    assert!(
        data_first > title_last,
        "single chart: data from row {data_first}, title down to row {title_last}"
    );

    let panels = |shared: &str, each: &str, data: bool| PanelFigure {
        title: shared.into(),
        panels: (0..3)
            .map(|_| prepare_chart(&chart(each, data), plot_buckets(PANEL_WIDTH)))
            .collect::<Result<Vec<_>, _>>()
            .expect("prepared"),
    };
    let each = "Panel title of some length";
    let each_reversed: String = each.chars().rev().collect();
    let (titled, w) = raster_figure(&panels(title, each, false));
    let (other, _) = raster_figure(&panels(&reversed, &each_reversed, false));
    let (full, _) = raster_figure(&panels(title, each, true));
    let title_rows = rows_changed(&titled, &other, w);
    let data_rows = rows_changed(&titled, &full, w);
    // Each panel: its titles (the shared one above the first) first, then its data.
    let top = |p: usize| 50 + p * PANEL_HEIGHT as usize;
    for p in 0..3 {
        let t_last = title_rows
            .iter()
            .copied()
            .filter(|r| *r < top(p + 1) && (p == 0 || *r >= top(p)))
            .max()
            .expect("panel title drawn");
        let d_first = data_rows
            .iter()
            .copied()
            .find(|r| *r >= top(p))
            .expect("panel data drawn");
        assert!(
            d_first > t_last && t_last >= top(p),
            "panel {p}: data from row {d_first}, its title down to row {t_last}"
        );
    }
}

/// A chart drawn into an in-memory bitmap of `size`, returning where its plotting area and
/// legend landed.
fn layout_of(p: &PreparedChart, legend_w: u32) -> chart::ChartLayout {
    output::ensure_fonts().expect("fonts");
    let (w, h) = CHART_SIZE;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    let root = plotters::prelude::BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
    let y_area = chart::y_area_width(&root, &p.y, &p.y_label);
    chart::draw_chart(&root, p, TITLE_PX, y_area, legend_w).expect("drawn")
}

/// Data over the whole plotting area and a legend of long labels and notes: the legend's
/// box lies wholly right of the plotting area, so it covers no data.
#[test]
fn legend_box_does_not_overlap_the_plotting_area() {
    let x: Vec<f64> = (0..2000).map(|i| f64::from(i) * 1e-3).collect();
    let fill = |k: f64| x.iter().map(|t| (t * k).sin()).collect::<Vec<f64>>();
    let chart = Chart {
        title: "legend placement".into(),
        x_label: "time [s]".into(),
        y_label: "pointing error [mrad]".into(),
        series: vec![
            Series::line(
                "none, a label long enough to wrap in the legend column",
                x.clone(),
                fill(40.0),
            ),
            Series::line("memoryless", x.clone(), fill(41.0)),
            Series::step("memory", x.clone(), fill(43.0)),
        ],
        bands: vec![HBand {
            lo: -0.1,
            hi: 0.1,
            label: "target +-0.1 mrad".into(),
        }],
        x_shades: vec![XShade {
            lo: f64::NEG_INFINITY,
            hi: 0.2,
            label: "outside the metrics window (not judged)".into(),
        }],
        notes: vec!["a note of some length that wraps onto several lines".into()],
        ..Chart::default()
    };
    let p = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepared");
    let layout = layout_of(&p, chart::legend_width(&p));
    let ((pl, pt), (pr, pb)) = layout.plot;
    let ((ll, lt), (lr, lb)) = layout.legend.expect("a legend is drawn");
    assert!(pr > pl && pb > pt && lr > ll && lb > lt);
    assert!(
        layout.legend_clear(),
        "legend {:?} overlaps plotting area {:?}",
        layout.legend,
        layout.plot
    );
    assert!(
        ll >= pr,
        "legend starts at x {ll}, plotting area ends at {pr}"
    );
    assert!(lr <= CHART_SIZE.0 as i32, "legend leaves the figure");
    // No legend: the plotting area takes the width.
    let bare = Chart {
        series: vec![Series::line("", x.clone(), fill(40.0))],
        bands: Vec::new(),
        x_shades: Vec::new(),
        notes: Vec::new(),
        ..chart
    };
    let p = prepare_chart(&bare, plot_buckets(CHART_SIZE.0)).expect("prepared");
    let layout = layout_of(&p, chart::legend_width(&p));
    assert!(layout.legend.is_none());
    assert!(layout.plot.1 .0 > pr);
}

/// Two curves that are the same within a small fraction of the axis are named in a note,
/// and every curve of a chart keeps its own dash pattern and marker.
#[test]
fn coinciding_curves_are_told_apart() {
    let x: Vec<f64> = (0..500).map(|i| f64::from(i) * 1e-2).collect();
    let a: Vec<f64> = x.iter().map(|t| t.sin()).collect();
    let b: Vec<f64> = a.iter().map(|v| v + 1e-4).collect();
    let c: Vec<f64> = a.iter().map(|v| v + 0.5).collect();
    let chart = Chart {
        series: vec![
            Series::line("memoryless", x.clone(), a).in_slot(1),
            Series::line("memory", x.clone(), b).in_slot(2),
            Series::line("none", x.clone(), c).in_slot(0),
        ],
        ..Chart::default()
    };
    let p = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepared");
    assert_eq!(p.notes.len(), 1, "{:?}", p.notes);
    assert!(
        p.notes[0].starts_with("memory coincides with memoryless"),
        "{}",
        p.notes[0]
    );
    let patterns: std::collections::HashSet<usize> = p.series.iter().map(|s| s.pattern).collect();
    assert_eq!(patterns.len(), 3);
    assert!(p.series.iter().all(|s| !s.markers.is_empty()));
    // Markers of different curves sit at different x.
    assert!(p.series[0].markers[0].0 != p.series[1].markers[0].0);
}

/// Dashes run on across the polyline's vertices and their total length follows the
/// pattern's duty cycle.
#[test]
fn dashes_follow_the_pattern() {
    let line: Vec<(f64, f64)> = (0..=10).map(|i| (f64::from(i) * 18.0, 0.0)).collect();
    let pieces = chart::dash_pieces(&line, &[12.0, 6.0]);
    let on: f64 = pieces
        .iter()
        .map(|p| p.windows(2).map(|w| (w[1].0 - w[0].0).abs()).sum::<f64>())
        .sum();
    assert_eq!(pieces.len(), 10);
    assert!((on - 120.0).abs() < 1e-9, "{on}");
    assert_eq!(chart::dash_pieces(&line, &[]).len(), 1);
}

/// A start-up transient outside the window that sets the scale: the axis fits the window,
/// the transient is marked off scale with a note, the shade covers the start-up.
#[test]
fn window_sets_the_scale_and_the_rest_is_marked_off_scale() {
    let t: Vec<f64> = (0..4000).map(|i| f64::from(i) * 1e-3).collect();
    let e: Vec<f64> = t
        .iter()
        .map(|t| {
            if *t < 0.5 {
                10.0 * (1.0 - t)
            } else {
                0.05 * (t * 20.0).sin()
            }
        })
        .collect();
    let chart = Chart {
        series: vec![Series::line("none", t, e)],
        bands: vec![HBand {
            lo: -0.1,
            hi: 0.1,
            label: "target".into(),
        }],
        x_shades: vec![XShade {
            lo: f64::NEG_INFINITY,
            hi: 1.0,
            label: "outside".into(),
        }],
        y_fit_x: Some((1.0, 4.0)),
        ..Chart::default()
    };
    let p = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepared");
    assert!(p.y.hi < 0.2 && p.y.lo > -0.2, "{} {}", p.y.lo, p.y.hi);
    assert!(!p.series[0].off_above.is_empty());
    assert!(p.series[0].off_above.iter().all(|x| *x < 0.6));
    assert!(p.notes.iter().any(|n| n.contains("off scale")));
    assert_eq!(p.shades.len(), 1);
    assert!((p.shades[0].lo - p.x.lo).abs() < 1e-12 && (p.shades[0].hi - 1.0).abs() < 1e-12);
    check_outputs(
        &save_chart(&chart, &out_dir("off_scale").join("window")).expect("drawn"),
        CHART_SIZE,
    );
}

/// Samples shown for context (a start-up transient before the metrics window) leave the
/// scale to the judged ones, are marked off scale where they leave it, and are drawn plain
/// in their grey, with one legend entry.
#[test]
fn context_samples_do_not_set_the_scale() {
    let x: Vec<f64> = (0..400).map(|i| f64::from(i) * 0.1 - 20.0).collect();
    let judged: Vec<f64> = x.iter().map(|v| 0.05 * (v * 0.3).sin()).collect();
    let transient: Vec<f64> = x
        .iter()
        .map(|v| {
            if v.abs() < 1.0 {
                -0.5 * (1.0 - v.abs())
            } else {
                f64::NAN
            }
        })
        .collect();
    let chart = Chart {
        series: vec![
            Series::line(
                "before metrics start (not judged)",
                x.clone(),
                transient.clone(),
            )
            .as_context(),
            Series::line("", x.clone(), transient).as_context(),
            Series::line("memory", x, judged).in_slot(2),
        ],
        ..Chart::default()
    };
    let p = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepared");
    assert!(p.y.lo > -0.1 && p.y.hi < 0.1, "{} {}", p.y.lo, p.y.hi);
    assert!(!p.series[0].off_below.is_empty());
    assert!(p.notes.iter().any(|n| n.contains("off scale")));
    let grey = RGBColor(CONTEXT_RGB[0], CONTEXT_RGB[1], CONTEXT_RGB[2]);
    for s in &p.series[..2] {
        assert_eq!((s.color, s.pattern, s.markers.len()), (grey, 0, 0));
    }
    // Only context: it sets the scale itself rather than leaving an empty axis.
    let alone = Chart {
        series: vec![chart.series[0].clone()],
        ..Chart::default()
    };
    let p = prepare_chart(&alone, plot_buckets(CHART_SIZE.0)).expect("prepared");
    assert!(p.y.lo <= -0.5, "{}", p.y.lo);
    check_outputs(
        &save_chart(&chart, &out_dir("context").join("context")).expect("drawn"),
        CHART_SIZE,
    );
}

/// Categories named on an axis: their names are its tick labels, nothing else is.
#[test]
fn named_axis_shows_the_names() {
    let chart = Chart {
        series: vec![Series::points("rmse", vec![0.3, 0.1], vec![2.0, 1.0])],
        y_names: vec![(1.0, "backlash".into()), (2.0, "runout".into())],
        y_range: Some((0.5, 2.5)),
        ..Chart::default()
    };
    let p = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepared");
    assert_eq!(p.y.major, vec![1.0, 2.0]);
    assert_eq!(p.y.label(1.0), "backlash");
    assert_eq!(p.y.label(2.0), "runout");
    assert_eq!(p.y.label(1.5), "");
    let svg = save_chart(&chart, &out_dir("named").join("names")).expect("drawn");
    let text = fs::read_to_string(&svg[1]).expect("svg");
    assert!(text.contains("backlash") && text.contains("runout"));
}

/// Values over three decades on a log colour scale use the whole scale (a linear one puts
/// nearly every cell in its lowest tenth); failed cells are crossed out.
#[test]
fn heatmap_log_colour_scale_spreads_decades() {
    let x: Vec<f64> = (0..12).map(f64::from).collect();
    let y: Vec<f64> = (0..10).map(f64::from).collect();
    let z: Vec<Vec<f64>> = y
        .iter()
        .map(|yv| {
            x.iter()
                .map(|xv| {
                    if *xv == 5.0 && *yv == 5.0 {
                        f64::NAN
                    } else {
                        0.01 * 10f64.powf((xv + yv) / 7.0)
                    }
                })
                .collect()
        })
        .collect();
    let map = Heatmap {
        title: "rms over two gains".into(),
        x_label: "kp".into(),
        y_label: "ki".into(),
        z_label: "rms_mrad".into(),
        x,
        y,
        z,
        contour: Some(0.1),
        log_z: true,
        ..Heatmap::default()
    };
    let tenths = |m: &Heatmap| {
        let p = prepare_heatmap(m).expect("prepared");
        let lowest = viridis(0.1);
        let low = p
            .cells
            .iter()
            .filter(|c| c.2 != MISSING_COLOR)
            .filter(|c| {
                // Colours of the lowest tenth of the scale lie between viridis(0) and (0.1).
                let d = |a: u8, b: u8| (i32::from(a) - i32::from(b)).abs();
                d(c.2 .0, lowest.0) + d(c.2 .1, lowest.1) + d(c.2 .2, lowest.2) < 40
                    || c.2 == viridis(0.0)
            })
            .count();
        (p, low)
    };
    let (p, low_log) = tenths(&map);
    assert!(p.log_z && p.z.log);
    assert_eq!(p.missing.len(), 1);
    assert!(!p.contour.as_ref().expect("contour").1.is_empty());
    let (_, low_lin) = tenths(&Heatmap {
        log_z: false,
        ..map.clone()
    });
    assert!(low_lin > 3 * low_log, "linear {low_lin}, log {low_log}");
    // A value without a logarithm keeps the scale linear.
    let mut zero = map.clone();
    zero.z[0][0] = 0.0;
    assert!(!prepare_heatmap(&zero).expect("prepared").log_z);
    check_outputs(
        &save_heatmap(&map, &out_dir("heat_log").join("map")).expect("drawn"),
        HEATMAP_SIZE,
    );
}

/// A legend line never ends in a number whose unit starts the next.
#[test]
fn a_number_keeps_its_unit_when_a_legend_wraps() {
    assert_eq!(
        chart::unbroken_words("scenario's design (20000 Hz)"),
        ["scenario's", "design", "(20000 Hz)"]
    );
    assert_eq!(
        chart::unbroken_words("target 0.1 mrad"),
        ["target", "0.1 mrad"]
    );
    assert_eq!(chart::unbroken_words("share 95 %"), ["share", "95 %"]);
}
