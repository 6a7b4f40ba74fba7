//! The PNG figures: valid PNGs of the documented size with the text and the
//! curves drawn, and clear errors (never a panic) on bad input.

use std::path::PathBuf;

use host_sim::output::plots::{
    convergence_size, figure_size, moving_average, plot_convergence, plot_group, plot_group_marked,
    plot_innovations, Curve, Innovations, SigmaSeries, HEADER_HEIGHT, INNOVATIONS_SIZE, MAX_PANELS,
    WIDTH,
};

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rollcal-plots-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Decoded RGB(A) image: (width, height, bytes per pixel, pixels).
fn decode(path: &std::path::Path) -> (u32, u32, usize, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    let bpp = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("unexpected colour type {other:?}"),
    };
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    (info.width, info.height, bpp, buf)
}

/// Number of pixels in rows `rows` whose colour is within 40 of `rgb`.
fn count_colour(
    img: &(u32, u32, usize, Vec<u8>),
    rows: std::ops::Range<u32>,
    rgb: [u8; 3],
) -> usize {
    let (w, _, bpp, buf) = img;
    let mut n = 0;
    for y in rows {
        for x in 0..*w {
            let i = (y as usize * *w as usize + x as usize) * bpp;
            let px = &buf[i..i + 3];
            if px
                .iter()
                .zip(rgb)
                .all(|(&a, b)| (a as i32 - b as i32).abs() <= 40)
            {
                n += 1;
            }
        }
    }
    n
}

/// Synthetic run like the estimator's: an error decaying from ~1000″ to a
/// noisy ~0.1″ level, σ from 3600″ to ~0.05″, σ_CRLB a bit below σ.
fn synthetic(n: usize) -> (Vec<f64>, Vec<[Vec<f64>; 3]>) {
    let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
    let mut state = 12345_u64;
    let mut noise = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let curves = (0..3)
        .map(|j| {
            let scale = 1.0 + j as f64;
            let sigma: Vec<f64> = t
                .iter()
                .map(|&ti| 3600.0 * (-ti / 40.0).exp() + 0.05 * scale)
                .collect();
            let error: Vec<f64> = t
                .iter()
                .zip(&sigma)
                .map(|(&ti, s)| 1000.0 * (-ti / 60.0).exp() * (ti / 30.0).cos() + s * noise())
                .collect();
            let crlb: Vec<f64> = sigma.iter().map(|s| 0.8 * s).collect();
            [error, sigma, crlb]
        })
        .collect();
    (t, curves)
}

fn curves<'a>(labels: &[&'a str], data: &'a [[Vec<f64>; 3]]) -> Vec<Curve<'a>> {
    labels
        .iter()
        .zip(data)
        .map(|(label, [error, sigma, crlb])| Curve {
            label,
            unit: "″",
            error,
            sigma,
            crlb,
        })
        .collect()
}

#[test]
fn writes_a_png_of_the_documented_size_with_text_and_curves() {
    let dir = temp_dir("synthetic");
    let path = dir.join("thaT.png");
    let (t, data) = synthetic(5400);
    let c = curves(&["thaT_1", "thaT_2", "thaT_3"], &data);
    plot_group(&path, "M2-ps: θaT (synthetic)", &t, &c).unwrap();
    let img = decode(&path);
    assert_eq!((img.0, img.1), figure_size(3));
    assert_eq!(figure_size(3), (WIDTH, HEADER_HEIGHT + 3 * 250));
    // The title is drawn: dark anti-aliased glyph pixels in its strip.
    assert!(count_colour(&img, 0..32, [0, 0, 0]) > 100, "no title text");
    // Each row has the error (blue) and the filter (vermilion) curves.
    for row in 0..3 {
        let rows = HEADER_HEIGHT + row * 250..HEADER_HEIGHT + (row + 1) * 250;
        assert!(
            count_colour(&img, rows.clone(), [0, 90, 181]) > 300,
            "row {row}: no error curve"
        );
        assert!(
            count_colour(&img, rows, [213, 94, 0]) > 300,
            "row {row}: no 3σ curve"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn non_finite_zero_and_degenerate_data_still_draw() {
    let dir = temp_dir("degenerate");
    let n = 500;
    let (t, mut data) = synthetic(n);
    // NaN and ±inf sprinkled into every series and the time axis.
    for (k, d) in data.iter_mut().enumerate() {
        for v in d.iter_mut() {
            v[7 + k] = f64::NAN;
            v[100] = f64::INFINITY;
            v[n - 1] = f64::NEG_INFINITY;
        }
    }
    let mut t_bad = t.clone();
    t_bad[50] = f64::NAN;
    let c = curves(&["a", "b", "c"], &data);
    let path = dir.join("nan.png");
    plot_group(&path, "NaN and inf", &t_bad, &c).unwrap();
    assert_eq!((decode(&path).0, decode(&path).1), figure_size(3));

    // All-zero data (error, σ and σ_CRLB).
    let zeros = vec![0.0; n];
    let z = [Curve {
        label: "zero",
        unit: "″",
        error: &zeros,
        sigma: &zeros,
        crlb: &zeros,
    }];
    let path = dir.join("zeros.png");
    plot_group(&path, "zeros", &t, &z).unwrap();
    assert_eq!((decode(&path).0, decode(&path).1), figure_size(1));

    // All values NaN, a single point, a constant time axis, negative σ.
    let nan = vec![f64::NAN; n];
    let all_nan = [Curve {
        label: "nan",
        unit: "″",
        error: &nan,
        sigma: &nan,
        crlb: &nan,
    }];
    plot_group(&dir.join("allnan.png"), "all NaN", &t, &all_nan).unwrap();
    let one = [Curve {
        label: "one",
        unit: "″",
        error: &[2.0],
        sigma: &[-1.0],
        crlb: &[0.5],
    }];
    plot_group(&dir.join("one.png"), "one point", &[10.0], &one).unwrap();
    let flat_t = vec![3.0; n];
    let flat = curves(&["flat"], &data[..1]);
    plot_group(&dir.join("flat.png"), "constant t", &flat_t, &flat).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let dir = temp_dir("errors");
    let path = dir.join("x.png");
    let (t, data) = synthetic(100);
    let c = curves(&["a"], &data);

    let e = plot_group(&path, "t", &[], &c).unwrap_err();
    assert!(e.contains("empty time axis"), "{e}");
    let e = plot_group(&path, "t", &t, &[]).unwrap_err();
    assert!(e.contains("no curve"), "{e}");

    let short = &data[0][1][..99];
    let bad = [Curve {
        label: "thgC_x",
        unit: "″",
        error: &data[0][0],
        sigma: short,
        crlb: &data[0][2],
    }];
    let e = plot_group(&path, "t", &t, &bad).unwrap_err();
    assert!(e.contains("thgC_x") && e.contains("sigma has 99"), "{e}");

    let many = vec![c[0]; MAX_PANELS + 1];
    let e = plot_group(&path, "t", &t, &many).unwrap_err();
    assert!(e.contains("at most"), "{e}");

    let nan_t = vec![f64::NAN; 100];
    let e = plot_group(&path, "t", &nan_t, &c).unwrap_err();
    assert!(e.contains("no finite time"), "{e}");

    // Unwritable destination: a directory that does not exist.
    let missing = dir.join("no-such-dir").join("x.png");
    let e = plot_group(&missing, "t", &t, &c).unwrap_err();
    assert!(e.contains("no-such-dir"), "{e}");
    assert!(!path.exists(), "no figure written on error");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Pixels of `rgb` (within 40) in the columns `cols` and rows `rows`.
fn count_in(
    img: &(u32, u32, usize, Vec<u8>),
    rows: std::ops::Range<u32>,
    cols: std::ops::Range<u32>,
    rgb: [u8; 3],
) -> usize {
    let (w, _, bpp, buf) = img;
    let mut n = 0;
    for y in rows {
        for x in cols.clone() {
            let i = (y as usize * *w as usize + x as usize) * bpp;
            if buf[i..i + 3]
                .iter()
                .zip(rgb)
                .all(|(&a, b)| (a as i32 - b as i32).abs() <= 40)
            {
                n += 1;
            }
        }
    }
    n
}

const SWITCH: [u8; 3] = [150, 90, 190];
const FILTER: [u8; 3] = [213, 94, 0];
const CRLB: [u8; 3] = [30, 30, 30];
const ERROR: [u8; 3] = [0, 90, 181];

#[test]
fn switches_are_marked_and_band_and_bound_both_show_where_they_coincide() {
    let dir = temp_dir("marked");
    let (t, mut data) = synthetic(5400);
    // The filter at the bound: σ_CRLB = σ (the case that hid the band).
    for d in &mut data {
        d[2] = d[1].clone();
    }
    let c = curves(&["a"], &data[..1]);
    let (plain, marked) = (dir.join("plain.png"), dir.join("marked.png"));
    plot_group(&plain, "no switches", &t, &c).unwrap();
    plot_group_marked(&marked, "switches", &t, &c, &[1800.0, 2700.0, 4500.0]).unwrap();
    let (p, m) = (decode(&plain), decode(&marked));
    let body = HEADER_HEIGHT..p.1;
    assert_eq!(count_in(&p, body.clone(), 0..WIDTH, SWITCH), 0);
    // Three lines in each of the two panels, ~200 px tall each.
    assert!(
        count_in(&m, body.clone(), 0..WIDTH, SWITCH) > 6 * 150,
        "switch lines not drawn"
    );
    // Both the filter's line and the bound's dashes are visible in both panels.
    for cols in [0..WIDTH / 2, WIDTH / 2..WIDTH] {
        let f = count_in(&m, body.clone(), cols.clone(), FILTER);
        let b = count_in(&m, body.clone(), cols.clone(), CRLB);
        assert!(f > 1000, "filter line hidden ({f} px in {cols:?})");
        assert!(b > 1000, "bound hidden ({b} px in {cols:?})");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_zoom_panel_does_not_clip_the_transient_into_bars() {
    let dir = temp_dir("bars");
    // An error of ±1000″ oscillating for the first fifth of the run (the
    // transient), then ~0.1″: clipped at the zoom's frame it filled the
    // panel with solid vertical bars.
    let (t, mut data) = synthetic(5400);
    for (k, e) in data[0][0].iter_mut().enumerate() {
        if k < 1000 {
            *e = if k % 2 == 0 { 1000.0 } else { -1000.0 };
        }
    }
    let c = curves(&["a"], &data[..1]);
    let path = dir.join("bars.png");
    plot_group(&path, "transient", &t, &c).unwrap();
    let img = decode(&path);
    // No column of the zoom panel is a solid bar of the error colour (the
    // clipped transient made every column of its first fifth one).
    let rows = HEADER_HEIGHT + 30..img.1 - 40;
    let height = (rows.end - rows.start) as usize;
    let worst = (WIDTH / 2 + 70..WIDTH - 20)
        .map(|x| count_in(&img, rows.clone(), x..x + 1, ERROR))
        .max()
        .unwrap();
    assert!(
        worst * 2 < height,
        "a column of the zoom panel is {worst} of {height} px of error colour"
    );
    // (Before the zoom panel started at the converged part, the ±1000″
    // samples clipped at its ±0.2″ frame made each column of the first
    // fifth a frame-high bar: worst ≈ height.) The error is drawn there.
    assert!(count_in(&img, rows, WIDTH / 2 + 70..WIDTH - 20, ERROR) > 1000);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn convergence_and_innovation_figures_have_their_size_and_content() {
    let dir = temp_dir("report-figs");
    let (t, data) = synthetic(2000);
    let series: Vec<SigmaSeries<'_>> = data
        .iter()
        .zip(["x", "y", "z"])
        .map(|(d, label)| SigmaSeries {
            label,
            unit: "″",
            sigma: &d[1],
            crlb: Some(&d[2]),
        })
        .collect();
    let path = dir.join("sigma.png");
    plot_convergence(&path, "σ(t)", &t, &series, &[700.0]).unwrap();
    let img = decode(&path);
    assert_eq!((img.0, img.1), convergence_size(3));
    let body = HEADER_HEIGHT..img.1;
    assert!(count_in(&img, body.clone(), 0..WIDTH, FILTER) > 300);
    assert!(count_in(&img, body.clone(), 0..WIDTH, CRLB) > 300);
    assert!(count_in(&img, body, 0..WIDTH, SWITCH) > 3 * 100);
    // Without σ_CRLB, and errors on bad input.
    let bare = [SigmaSeries {
        label: "x",
        unit: "″",
        sigma: &data[0][1],
        crlb: None,
    }];
    plot_convergence(&dir.join("bare.png"), "σ", &t, &bare, &[]).unwrap();
    let short = [SigmaSeries {
        label: "x",
        unit: "″",
        sigma: &data[0][1][..5],
        crlb: None,
    }];
    let e = plot_convergence(&dir.join("bad.png"), "σ", &t, &short, &[]).unwrap_err();
    assert!(e.contains("sigma has 5"), "{e}");
    assert!(plot_convergence(&dir.join("bad.png"), "σ", &[], &bare, &[]).is_err());

    // Innovations: unit-variance components, NIS = their square sum.
    let mut state = 7_u64;
    let mut gauss = move || {
        let mut s = 0.0;
        for _ in 0..12 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            s += (state >> 11) as f64 / (1u64 << 53) as f64;
        }
        s - 6.0
    };
    let white: Vec<Vec<f64>> = (0..2000)
        .map(|_| (0..3).map(|_| gauss()).collect())
        .collect();
    let nis: Vec<f64> = white
        .iter()
        .map(|w| w.iter().map(|v| v * v).sum())
        .collect();
    let path = dir.join("innov.png");
    let u = Innovations {
        t_s: &t,
        nis: &nis,
        white: &white,
        dof: 3,
        window: 100,
        band: host_sim::output::html::nis_band(100, 3),
        components: &["accel x", "accel y", "accel z"],
    };
    plot_innovations(&path, "innovations", &u, &[500.0, 1500.0]).unwrap();
    let img = decode(&path);
    assert_eq!((img.0, img.1), INNOVATIONS_SIZE);
    assert!(count_in(&img, HEADER_HEIGHT..img.1, 0..WIDTH, ERROR) > 1000);
    assert!(count_in(&img, HEADER_HEIGHT..img.1, 0..WIDTH, SWITCH) > 4 * 150);
    let e = plot_innovations(
        &path,
        "x",
        &Innovations {
            nis: &nis[..10],
            ..u
        },
        &[],
    )
    .unwrap_err();
    assert!(e.contains("10 NIS values"), "{e}");
    assert_eq!(
        moving_average(&[1.0, 3.0, 5.0, 7.0], 2),
        [1.0, 2.0, 4.0, 6.0]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Renders the figures of a real paper-scenario run (configuration M2-ps,
/// seed 1) for looking at: `cargo test --release -p host-sim --test it
/// plots:: -- --ignored`, into `$ROLLCAL_PLOTS_DIR` (default: a temp directory,
/// printed). σ_CRLB is the final bound, drawn as a constant.
#[test]
#[ignore = "slow (full estimator run); writes figures to look at"]
fn real_run_figures() {
    use host_sim::analysis::runner::{crlb_sigma, run_filter, Estimator};
    use host_sim::sim::scenario::{Scenario, ARCSEC};
    use host_sim::sim::truth::{simulate, truth_state, SimOptions};
    use rollcal::geometry::wrap_angle;
    use rollcal::models::ConfigId;

    let dir = std::env::var_os("ROLLCAL_PLOTS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| temp_dir("real"));
    std::fs::create_dir_all(&dir).unwrap();
    let id = ConfigId::M2Ps;
    let scenario = Scenario::paper();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: 1,
            noise: true,
            earth_rate: true,
        },
    );
    let run = run_filter(id, &scenario, &sim, true, Estimator::default(), None, true).unwrap();
    let crlb = crlb_sigma(id, &scenario, &sim, true).unwrap();
    let states = id.states();
    let t: Vec<f64> = run.history.iter().map(|(t, _, _)| *t).collect();
    let n = states.len();
    let mut err = vec![Vec::new(); n];
    let mut sig = vec![Vec::new(); n];
    for ((_, x, s), sample) in run.history.iter().zip(&sim.samples) {
        let truth = truth_state(id, &sim.params, &sample.truth);
        for i in 0..n {
            err[i].push(wrap_angle(x[i] - truth[i]) / ARCSEC);
            sig[i].push(s[i] / ARCSEC);
        }
    }
    let cr: Vec<Vec<f64>> = crlb.iter().map(|c| vec![c / ARCSEC; t.len()]).collect();
    let mut groups: Vec<&str> = states.iter().map(|s| s.group.as_str()).collect();
    groups.dedup();
    for g in groups {
        let c: Vec<Curve<'_>> = (0..n)
            .filter(|&i| states[i].group.as_str() == g)
            .map(|i| Curve {
                label: states[i].name,
                unit: "″",
                error: &err[i],
                sigma: &sig[i],
                crlb: &cr[i],
            })
            .collect();
        let path = dir.join(format!("{}-{g}.png", id.as_str()));
        plot_group_marked(
            &path,
            &format!("{}: {g}, seed 1", id.as_str()),
            &t,
            &c,
            &host_sim::sim::segments::switch_times(&run.segments),
        )
        .unwrap();
        let img = decode(&path);
        assert_eq!((img.0, img.1), figure_size(c.len()));
        println!("wrote {}", path.display());
    }
}
