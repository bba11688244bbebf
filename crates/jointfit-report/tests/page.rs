//! The report page end to end on a synthetic trial: structure, figures, escaping, the offline
//! rule, and (where chromium is installed, and always in CI) a real rendering to PNG.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use jointfit::ik::IkOptions;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion, SkinNoise};
use jointfit_report::analyze::{analyze, parameter_rows};
use jointfit_report::check::{external_references, parse, Element};
use jointfit_report::{html, write_report, Convergence, Interval, ReportInput};

/// A marker name that breaks any page that does not escape it.
const NASTY: &str = r#"<script>alert("x")</script> & R'ASIS"#;

struct Built {
    input: ReportInput,
    page: String,
}

/// A report of the built-in leg on a noisy synthetic trial: the "fitted" model is the truth,
/// the baseline the nominal model; one marker carries a hostile name.
fn build() -> Built {
    let mut spec = lower_limb(Side::Right);
    spec.markers[0].name = NASTY.to_string();
    let model = Model::compile(&spec).unwrap();
    let truth = perturbed_params(&model, 0.3, 7);
    let coords = coordinates(&model, Motion::All, 60).unwrap();
    let (trial, _) = markers(&model, &truth, &coords, 50.0, Some(&SkinNoise::default()));
    let nominal = model.nominal_params();
    let mut input = ReportInput {
        title: "synthetic <leg> & co".into(),
        baseline_label: "nominal model".into(),
        fitted_label: "true model".into(),
        ..ReportInput::default()
    };
    analyze(
        &mut input,
        &model,
        &truth,
        Some(&nominal),
        &[("synthetic.trc".to_string(), &trial)],
        &IkOptions::default(),
    )
    .unwrap();
    let free: Vec<usize> = (0..model.parameters().len())
        .filter(|i| i % 2 == 0)
        .collect();
    input.parameters = parameter_rows(&model, &truth, Some(&nominal), Some(&free));
    // An interval on one parameter, as the uncertainty module will provide.
    let (name, fitted) = (input.parameters[0].name.clone(), input.parameters[0].fitted);
    let iv = Interval {
        se: 1.5,
        lower: fitted - 2.94,
        upper: fitted + 2.94,
        level: 0.95,
    };
    assert!(input.set_interval(&name, iv));
    assert!(!input.set_interval("no_such_parameter", iv));
    input.convergence = Some(Convergence {
        method: "pso".into(),
        stages: vec![
            ("particle swarm".into(), vec![900.0, 400.0, 120.0, 80.0]),
            ("joint polish".into(), vec![80.0, 31.0, 30.2, 30.19999]),
        ],
        iterations: 6,
        evaluations: 70,
        converged: true,
        seconds: 1.25,
        ..Convergence::default()
    });
    input.settings = vec![
        (
            "command line".into(),
            "jointfit calibrate 'a b.toml' x.trc".into(),
        ),
        ("jointfit version".into(), "0.1.0".into()),
        ("date".into(), jointfit_report::utc_now()),
    ];
    let page = html::render(&input);
    Built { input, page }
}

fn svgs(e: &Element) -> Vec<&Element> {
    e.find_all("svg")
}

/// Number of points drawn by the data paths (`M`/`L` commands) of an SVG with a given stroke.
fn points_with_stroke(svg: &Element, color: &str) -> usize {
    svg.find_all("path")
        .into_iter()
        .filter(|p| p.attr("stroke") == Some(color))
        .map(|p| {
            let d = p.attr("d").unwrap_or("");
            d.matches(['M', 'L']).count()
        })
        .sum()
}

#[test]
fn page_is_well_formed_offline_and_complete() {
    let Built { input, page } = build();
    let root = parse(&page).unwrap_or_else(|e| panic!("not well formed: {e}"));
    assert_eq!(root.name, "html");
    let refs = external_references(&root, &page);
    assert!(refs.is_empty(), "external references: {refs:?}");
    for id in [
        "summary",
        "fig-frame-error",
        "fig-marker-rms",
        "fig-joint-angles",
        "tbl-parameters",
        "fig-convergence",
        "tbl-settings",
    ] {
        assert!(root.by_id(id).is_some(), "missing #{id}");
    }
    for svg in svgs(&root) {
        let vb = svg.attr("viewBox").expect("every svg has a viewBox");
        let nums: Vec<f64> = vb.split(' ').map(|v| v.parse().unwrap()).collect();
        assert!(nums.len() == 4 && nums[2] > 0.0 && nums[3] > 0.0, "{vb}");
    }
    // Marker error: one chart, both models, one point per frame each.
    let frames = input.trials[0].time.len();
    let fe = root.by_id("fig-frame-error").unwrap();
    assert_eq!(svgs(fe).len(), 1);
    assert_eq!(points_with_stroke(svgs(fe)[0], html::BASELINE), frames);
    assert_eq!(points_with_stroke(svgs(fe)[0], html::FITTED), frames);
    // Per-marker bars: two bars per marker.
    let mr = root.by_id("fig-marker-rms").unwrap();
    let bars = mr
        .find_all("rect")
        .into_iter()
        .filter(|r| r.children.iter().any(|c| c.name == "title"))
        .count();
    assert_eq!(bars, 2 * input.markers.len());
    // Joint angles: a panel per coordinate, with its name as the title.
    let ja = root.by_id("fig-joint-angles").unwrap();
    let titles: Vec<String> = svgs(ja)
        .iter()
        .filter_map(|s| s.children.iter().find(|c| c.name == "title"))
        .map(|t| t.all_text())
        .collect();
    let names: Vec<&str> = input.trials[0]
        .coords
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    assert_eq!(titles.len(), names.len());
    for n in &names {
        assert!(titles.iter().any(|t| t == n), "no panel for {n}");
    }
    // Parameters: a row per parameter, interval filled where given, fixed ones marked.
    let table = root.by_id("tbl-parameters").unwrap();
    let rows: Vec<&Element> = table
        .find_all("tr")
        .into_iter()
        .filter(|r| r.attr("class") != Some("group") && r.find_all("th").is_empty())
        .collect();
    assert_eq!(rows.len(), input.parameters.len());
    assert!(
        rows[0].all_text().contains("±2.94"),
        "{}",
        rows[0].all_text()
    );
    assert!(table.all_text().contains("95% interval"));
    assert!(!rows[1].all_text().contains('±'));
    assert_eq!(rows[1].attr("class"), Some("fixed"));
    // Convergence: a log-scale chart per view with both stages.
    let cv = root.by_id("fig-convergence").unwrap();
    assert_eq!(svgs(cv).len(), 2);
    assert!(cv.all_text().contains("particle swarm"));
    // Settings: command line shown verbatim.
    let st = root.by_id("tbl-settings").unwrap();
    assert!(st
        .all_text()
        .contains("jointfit calibrate 'a b.toml' x.trc"));
}

#[test]
fn text_from_files_is_escaped() {
    let Built { page, .. } = build();
    assert!(!page.contains(NASTY));
    assert!(!page.contains("<script"));
    assert!(!page.contains("synthetic <leg>"));
    let root = parse(&page).unwrap();
    // The name survives as text: in the bar chart's row label and in the page title.
    let mr = root.by_id("fig-marker-rms").unwrap();
    assert!(mr.all_text().contains(NASTY), "marker name lost");
    let title = &root.find_all("title")[0];
    assert_eq!(title.all_text(), "synthetic <leg> & co");
}

#[test]
fn truth_beats_nominal_in_the_numbers_shown() {
    let Built { input, .. } = build();
    let (base, fit) = input.overall_rms_mm;
    let base = base.unwrap();
    // Skin noise up to 10 mm per axis; the true model explains everything else.
    assert!(fit < base, "{fit} vs {base}");
    assert!(fit > 1.0 && fit < 15.0, "{fit}");
    for m in &input.markers {
        assert!(m.fitted_mm.is_finite() && m.baseline_mm.unwrap().is_finite());
    }
}

#[test]
fn written_atomically_into_a_new_directory() {
    let Built { input, page } = build();
    let dir = jointfit_testkit::scratch("report");
    let path = write_report(&dir.join("nested"), &input).unwrap();
    assert_eq!(path, dir.join("nested/index.html"));
    let written = std::fs::read_to_string(&path).unwrap();
    // Rendering is deterministic for the same input.
    assert_eq!(written, page);
    let names: Vec<_> = std::fs::read_dir(dir.join("nested")).unwrap().collect();
    assert_eq!(names.len(), 1, "temporary files left behind");
    // A file where the directory should be: an error naming the path.
    let blocker = dir.join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let err = write_report(&blocker, &input).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}: exists and is not a directory (a report is written to DIR/index.html)",
            blocker.display()
        )
    );
    // The same check alone, as a front end makes it before a long fit.
    assert_eq!(
        jointfit_report::check_dir(&blocker)
            .unwrap_err()
            .to_string(),
        err
    );
    jointfit_report::check_dir(&dir.join("not-yet")).unwrap();
    jointfit_report::check_dir(&dir).unwrap();
}

fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|d| ["chromium", "chromium-browser"].map(|n| d.join(n)))
        .find(|p| p.is_file())
}

/// Renders `html` headless to a PNG of `width × height` CSS pixels.
fn screenshot(browser: &Path, html: &Path, png: &Path, width: u32, height: u32) {
    let profile = html.with_extension("profile");
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("--window-size={width},{height}"))
        .arg(format!("file://{}", html.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromium starts");
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "chromium failed: {status}");
            break;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("chromium did not finish within 120 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let _ = std::fs::remove_dir_all(&profile);
}

/// Fraction of pixels close to `rgb` (each channel within `tol`).
fn fraction_near(pixels: &[[u8; 3]], rgb: [u8; 3], tol: i32) -> f64 {
    let n = pixels
        .iter()
        .filter(|p| (0..3).all(|k| (p[k] as i32 - rgb[k] as i32).abs() <= tol))
        .count();
    n as f64 / pixels.len() as f64
}

fn hex(c: &str) -> [u8; 3] {
    let v = u32::from_str_radix(c.trim_start_matches('#'), 16).unwrap();
    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
}

#[test]
fn renders_in_headless_chromium() {
    let Some(browser) = chromium() else {
        assert!(
            !jointfit_testkit::in_ci(),
            "chromium is not installed; CI must have it (.ci/run)"
        );
        eprintln!("skipped: chromium not installed");
        return;
    };
    let Built { input, .. } = build();
    let dir = jointfit_testkit::scratch("render");
    let html = write_report(&dir, &input).unwrap();
    let png = dir.join("shot.png");
    let (w, h) = (1280u32, 3000u32);
    screenshot(&browser, &html, &png, w, h);
    let bytes = std::fs::read(&png).expect("a screenshot was written");
    assert!(
        bytes.len() > 50_000,
        "suspiciously small PNG: {} bytes",
        bytes.len()
    );
    let decoder = png::Decoder::new(std::io::Cursor::new(&bytes));
    let mut reader = decoder.read_info().expect("a valid PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG pixels");
    assert_eq!((info.width, info.height), (w, h));
    let channels = info.color_type.samples();
    assert!(channels >= 3 && info.bit_depth == png::BitDepth::Eight);
    let pixels: Vec<[u8; 3]> = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let white = fraction_near(&pixels, [255, 255, 255], 3);
    let blue = fraction_near(&pixels, hex(html::FITTED), 40);
    let orange = fraction_near(&pixels, hex(html::BASELINE), 40);
    eprintln!("screenshot: {white:.3} white, {blue:.4} fitted blue, {orange:.4} baseline orange");
    assert!(white < 0.97, "page is (nearly) blank: {white:.3} white");
    assert!(white > 0.5, "page is not on a white background: {white:.3}");
    // The fitted-model blue and the baseline orange are drawn (lines, bars, gauges).
    assert!(blue > 0.002, "little fitted-model colour: {blue}");
    assert!(orange > 0.0003, "little baseline colour: {orange}");
    // Content in the top and in the bottom half (the page is laid out, not clipped).
    let row_has_ink = |y: u32| {
        pixels[(y * w) as usize..((y + 1) * w) as usize]
            .iter()
            .any(|p| p.iter().any(|c| *c < 200))
    };
    assert!((0..h / 2).any(row_has_ink));
    assert!((h / 2..h).any(row_has_ink));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parameters_at_a_bound_are_called_out() {
    let Built { mut input, page } = build();
    assert!(!page.contains("at a bound"));
    // Parameter 2 is free in `build`; put it on its upper bound, and a fixed one on a bound.
    input.parameters[2].fitted = input.parameters[2].upper;
    input.parameters[3].fitted = input.parameters[3].lower;
    let root = parse(&html::render(&input)).unwrap();
    let section = root.by_id("sec-parameters").unwrap().all_text();
    let name = &input.parameters[2].name;
    assert!(
        section.contains("One parameter ended at a bound"),
        "{section}"
    );
    assert!(
        section.contains(&format!("({name}): the fit would have moved it further")),
        "{section}"
    );
    let rows: Vec<&Element> = root
        .by_id("tbl-parameters")
        .unwrap()
        .find_all("tr")
        .into_iter()
        .filter(|r| r.all_text().contains("at bound"))
        .collect();
    assert_eq!(rows.len(), 1);
    assert!(rows[0].all_text().starts_with(name.as_str()));
}

/// A trial without one of the model's markers (the static-only markers of a subject model,
/// say) is shown as the fit used it: that marker missing in every frame, said in a note, its
/// bar "n/a"; the other markers' errors are those of the trial without the marker, solved
/// directly. A trial with none of the model's markers is a one-line error.
#[test]
fn a_trial_lacking_a_model_marker_is_reported_with_a_note() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let truth = perturbed_params(&model, 0.3, 7);
    let coords = coordinates(&model, Motion::All, 40).unwrap();
    let (trial, _) = markers(&model, &truth, &coords, 50.0, Some(&SkinNoise::default()));
    let dropped = model.markers()[5].name.clone();
    let kept: Vec<&str> = trial
        .labels()
        .iter()
        .map(|l| l.as_str())
        .filter(|l| *l != dropped)
        .collect();
    let partial = trial.select(&kept).unwrap();
    let mut input = ReportInput::default();
    let trials = [("partial.trc".to_string(), &partial)];
    analyze(
        &mut input,
        &model,
        &truth,
        None,
        &trials,
        &IkOptions::default(),
    )
    .unwrap();
    assert_eq!(input.notes.len(), 1, "{:?}", input.notes);
    assert!(
        input.notes[0].starts_with(&format!(
            "partial.trc: the trial lacks model markers {dropped}; they count as missing"
        )),
        "{:?}",
        input.notes
    );
    assert!(input.markers[5].fitted_mm.is_nan());
    // Oracle: the same errors from the library's IK with the marker absent from the map.
    let (map, absent) = jointfit::ik::MarkerMap::allowing_absent(&model, partial.labels());
    assert_eq!(absent, std::slice::from_ref(&dropped));
    let fit =
        jointfit::ik::trial_fit::solve_trial(&model, &truth, &partial, &map, &IkOptions::default())
            .unwrap();
    for j in (0..model.markers().len()).filter(|&j| j != 5) {
        let direct = jointfit::ik::trial_fit::rms(fit.errors.iter().map(|e| e[j])) * 1e3;
        assert_eq!(input.markers[j].fitted_mm, direct, "marker {j}");
    }
    input.parameters = parameter_rows(&model, &truth, None, None);
    let root = parse(&html::render(&input)).unwrap();
    let bars = root.by_id("fig-marker-rms").unwrap().all_text();
    assert!(bars.contains("n/a"), "{bars}");
    assert!(root.all_text().contains("lacks model markers"));

    let none = trial.select(&[]).unwrap();
    let err = analyze(
        &mut ReportInput::default(),
        &model,
        &truth,
        None,
        &[("empty.trc".to_string(), &none)],
        &IkOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.starts_with("empty.trc: no label of the trial names a model marker"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1);
}
