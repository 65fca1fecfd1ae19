//! Every SVG the reports write, checked as a reader would see it: the
//! sensitivity report (with a depth where nothing is visible), a one-trial
//! reproduction of every experiment and a tiny search with its winner's
//! validation, all through the library pipelines into a temporary directory.
//! Each `<text>` is checked for float noise in tick labels, for staying
//! inside the view box and for overlapping no other text.
//!
//! A text's box is 0.6 × font size per character wide and reaches from
//! 0.8 × font size above its baseline to 0.2 × below; `text-anchor` places
//! it and `rotate(-90 x y)` turns it about its anchor.

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::montecarlo::{MonteCarloConfig, DEFAULT_GROSS_THRESHOLD_DEG};
use layout_opt::observer::Silent;
use layout_opt::pnp::Solver;
use layout_opt::reproduce::workflow::ReproduceConfig;
use layout_opt::reproduce::{Config, Experiment};
use layout_opt::scenario::{Range, ScenarioGrid};
use layout_opt::search::SearchConfig;
use layout_opt::validate::workflow::WorkflowConfig;
use layout_opt::validate::ValidateConfig;
use std::path::{Path, PathBuf};

const WIDTH_EM: f64 = 0.6;
const ASCENT_EM: f64 = 0.8;
const DESCENT_EM: f64 = 0.2;

/// One `<text>` element of an SVG.
#[derive(Debug, Clone)]
struct Text {
    class: String,
    content: String,
    left: f64,
    top: f64,
    right: f64,
    bottom: f64,
}

fn attribute(tag: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    let end = start + tag[start..].find('"')?;
    Some(tag[start..end].to_string())
}

fn number(tag: &str, name: &str) -> f64 {
    attribute(tag, name)
        .unwrap_or_else(|| panic!("no {name} in {tag}"))
        .parse()
        .unwrap_or_else(|_| panic!("{name} is not a number in {tag}"))
}

fn unescape(text: &str) -> String {
    text.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&amp;", "&")
}

/// The view box and every text of an SVG we wrote.
fn texts(svg: &str) -> ((f64, f64, f64, f64), Vec<Text>) {
    let open = svg.find("<svg").expect("an <svg> element");
    let head = &svg[open..open + svg[open..].find('>').unwrap()];
    let view: Vec<f64> = attribute(head, "viewBox")
        .expect("a viewBox")
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(start) = rest.find("<text") {
        rest = &rest[start..];
        let tag_end = rest.find('>').unwrap();
        let tag = &rest[..tag_end];
        let close = rest.find("</text>").expect("a closed <text>");
        let content = unescape(&rest[tag_end + 1..close]);
        assert!(!content.contains('<'), "nested markup in {tag}");
        let size = number(tag, "font-size");
        let (x, y) = (number(tag, "x"), number(tag, "y"));
        let width = WIDTH_EM * size * content.chars().count() as f64;
        let anchor = attribute(tag, "text-anchor").unwrap_or_else(|| "start".into());
        let shift = match anchor.as_str() {
            "start" => 0.0,
            "middle" => -0.5 * width,
            "end" => -width,
            other => panic!("unknown anchor {other}"),
        };
        let (left, top, right, bottom) = match attribute(tag, "transform") {
            None => (
                x + shift,
                y - ASCENT_EM * size,
                x + shift + width,
                y + DESCENT_EM * size,
            ),
            Some(t) if t.starts_with("rotate(-90 ") => (
                x - ASCENT_EM * size,
                y - shift - width,
                x + DESCENT_EM * size,
                y - shift,
            ),
            Some(t) => panic!("unexpected transform {t}"),
        };
        out.push(Text {
            class: attribute(tag, "class").unwrap_or_default(),
            content,
            left,
            top,
            right,
            bottom,
        });
        rest = &rest[close..];
    }
    ((view[0], view[1], view[2], view[3]), out)
}

/// Decimal places of `label` and the fewest its value needs, if it is a
/// plain number.
fn decimals(label: &str) -> Option<(usize, usize)> {
    let plain = label.trim_end_matches('%');
    if plain.contains('e') {
        return None;
    }
    let value: f64 = plain.parse().ok()?;
    let used = plain.split_once('.').map_or(0, |(_, d)| d.len());
    // The fewest places that keep the value (to 12 significant digits).
    let needed = (0..=used)
        .find(|&places| {
            let rounded: f64 = format!("{value:.places$}").parse().unwrap();
            (rounded - value).abs() <= 1e-12 * value.abs().max(1e-300)
        })
        .unwrap_or(used);
    Some((used, needed))
}

fn significant_digits(label: &str) -> usize {
    let mantissa = label.split('e').next().unwrap();
    mantissa
        .chars()
        .filter(char::is_ascii_digit)
        .collect::<String>()
        .trim_start_matches('0')
        .trim_end_matches('0')
        .len()
}

/// Every problem found in one SVG.
fn problems(path: &Path) -> Vec<String> {
    let svg = std::fs::read_to_string(path).unwrap();
    let name = path.display();
    let ((vx, vy, vw, vh), texts) = texts(&svg);
    let mut found = Vec::new();
    for t in &texts {
        if t.left < vx - 0.5
            || t.top < vy - 0.5
            || t.right > vx + vw + 0.5
            || t.bottom > vy + vh + 0.5
        {
            found.push(format!("{name}: '{}' leaves the view box", t.content));
        }
    }
    for (i, a) in texts.iter().enumerate() {
        for b in &texts[i + 1..] {
            let overlap = a.left < b.right - 0.5
                && b.left < a.right - 0.5
                && a.top < b.bottom - 0.5
                && b.top < a.bottom - 0.5;
            if overlap {
                found.push(format!("{name}: '{}' overlaps '{}'", a.content, b.content));
            }
        }
    }
    found.extend(style_problems(&name.to_string(), &svg));
    for class in ["tick-x", "tick-y"] {
        let labels: Vec<&Text> = texts.iter().filter(|t| t.class == class).collect();
        let needed = labels
            .iter()
            .filter_map(|t| decimals(&t.content))
            .map(|d| d.1)
            .max()
            .unwrap_or(0);
        for t in labels {
            if significant_digits(&t.content) > 4 {
                found.push(format!(
                    "{name}: tick label '{}' has float noise",
                    t.content
                ));
            }
            match decimals(&t.content) {
                Some((used, _)) if used > needed => found.push(format!(
                    "{name}: tick label '{}' has more decimals than its axis needs ({needed})",
                    t.content
                )),
                None if !t.content.contains('e') => found.push(format!(
                    "{name}: tick label '{}' is not a number",
                    t.content
                )),
                _ => {}
            }
        }
    }
    found
}

/// The hue (degrees) and saturation of `#rrggbb`.
fn hue_saturation(colour: &str) -> Option<(f64, f64)> {
    let hex = colour.strip_prefix('#')?;
    if hex.len() != 6 {
        return None;
    }
    let channel = |k: usize| {
        u8::from_str_radix(&hex[k..k + 2], 16)
            .ok()
            .map(|v| v as f64 / 255.0)
    };
    let (r, g, b) = (channel(0)?, channel(2)?, channel(4)?);
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    let chroma = max - min;
    if chroma <= 0.0 {
        return Some((0.0, 0.0));
    }
    let hue = if max == r {
        60.0 * ((g - b) / chroma).rem_euclid(6.0)
    } else if max == g {
        60.0 * ((b - r) / chroma + 2.0)
    } else {
        60.0 * ((r - g) / chroma + 4.0)
    };
    Some((hue, chroma / max))
}

/// Problems with how series and colour scales are told apart: more than
/// [`layout_opt::report::plots::MAX_SERIES_PER_PANEL`] series in one legend,
/// two series of one legend with the same dash and marker (in grey they
/// differ only in lightness), and filled cells that set red against green.
fn style_problems(name: &str, svg: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut legends: Vec<(String, Vec<(String, String)>)> = Vec::new();
    for tag in svg
        .split('<')
        .filter(|t| t.starts_with("g class=\"legend-entry\""))
    {
        let legend = attribute(tag, "data-legend").unwrap_or_default();
        let style = (
            attribute(tag, "data-dash").unwrap_or_default(),
            attribute(tag, "data-marker").unwrap_or_default(),
        );
        match legends.iter_mut().find(|(l, _)| *l == legend) {
            Some((_, styles)) => styles.push(style),
            None => legends.push((legend, vec![style])),
        }
    }
    for (_, styles) in &legends {
        if styles.len() > layout_opt::report::plots::MAX_SERIES_PER_PANEL {
            found.push(format!("{name}: {} series in one panel", styles.len()));
        }
        for (i, a) in styles.iter().enumerate() {
            if styles[i + 1..].contains(a) {
                found.push(format!(
                    "{name}: two series drawn with dash {} and marker {}",
                    a.0, a.1
                ));
            }
        }
    }
    let fills: Vec<(f64, f64)> = svg
        .split('<')
        .filter(|t| t.starts_with("rect"))
        .filter_map(|t| attribute(t, "fill"))
        .filter_map(|c| hue_saturation(&c.to_ascii_lowercase()))
        .filter(|&(_, saturation)| saturation >= 0.25)
        .collect();
    let red = fills.iter().any(|&(h, _)| !(20.0..340.0).contains(&h));
    let green = fills.iter().any(|&(h, _)| (75.0..165.0).contains(&h));
    if red && green {
        found.push(format!("{name}: a colour scale sets red against green"));
    }
    found
}

/// Placeholder text in a report: empty brackets, a lone "?" as a value,
/// "NaN".
fn placeholders(name: &str, text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let lone_question = line
            .split(|c: char| c.is_whitespace() || c == '|' || c == ',' || c == ';')
            .any(|word| word.trim_matches(|c: char| "()°%".contains(c)) == "?")
            || line
                .as_bytes()
                .windows(3)
                .any(|w| w[0].is_ascii_digit() && w[1] == b'.' && w[2] == b'?');
        for (bad, what) in [
            ("()", "empty brackets"),
            ("[]", "empty brackets"),
            ("NaN", "NaN"),
        ] {
            if line.contains(bad) {
                found.push(format!("{name}:{}: {what}: {line}", number + 1));
            }
        }
        if lone_question {
            found.push(format!("{name}:{}: '?' as a value: {line}", number + 1));
        }
    }
    found
}

fn svgs(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            svgs(&path, out);
        } else if path.extension().is_some_and(|e| e == "svg") {
            out.push(path);
        }
    }
}

fn markdown_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            markdown_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "md") {
            out.push(path);
        }
    }
}

fn write_reports(dir: &Path) {
    // Sensitivity: every solver (every style at once); at 200 mm the paper's
    // biprism leaves the image, so the depth plot has an empty value.
    let validate = ValidateConfig {
        layout: Layout::paper_biprism(),
        camera: Camera::paper(),
        volume: layout_opt::volume::WorkingVolume::Grid(
            ScenarioGrid::new(
                "200,400,700".parse().unwrap(),
                "0,50,100".parse().unwrap(),
                Range::single(0.0),
                "-40,0,40".parse().unwrap(),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.5),
            )
            .unwrap(),
        ),
        monte_carlo: MonteCarloConfig {
            trials: 4,
            seed: 3,
            solvers: Solver::ALL.to_vec(),
            noise: Default::default(),
            gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
            observation: Default::default(),
        },
        identifiability: layout_opt::validate::IdentifiabilityCheck {
            trials: 4,
            ..Default::default()
        },
        fabrication_sigma_mm: 0.0,
        camera_sigma: Default::default(),
        structure: Some(Default::default()),
        max_hidden: layout_opt::visibility::DEFAULT_MAX_HIDDEN,
        command: "plots test".into(),
    };
    let sensitivity = WorkflowConfig::new(validate, dir.join("sensitivity"));
    layout_opt::validate::workflow::run(&sensitivity, &mut Silent).unwrap();

    let reproduce = ReproduceConfig {
        experiments: Config {
            experiments: Experiment::ALL.to_vec(),
            seed: 3,
            trials: Some(1),
            quick: true,
            camera: None,
        },
        command: "plots test".into(),
        out_dir: dir.join("paper"),
    };
    layout_opt::reproduce::workflow::run(&reproduce, &mut Silent).unwrap();

    let mut search = SearchConfig::new("tiny", &dir.join("search"));
    search.volume = layout_opt::volume::WorkingVolume::Grid(
        ScenarioGrid::new(
            "200,500,800".parse().unwrap(),
            "0,60".parse().unwrap(),
            Range::single(0.0),
            "-40..40:20".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap(),
    );
    search.search.starts = 2;
    search.search.iterations = 40;
    search.compare_trials = 3;
    search.identify_trials = 2;
    search.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
    search.command = "plots test".into();
    layout_opt::search::workflow::run(&search, &mut Silent).unwrap();
}

#[test]
fn every_report_svg_has_clean_legible_text() {
    let dir = tempfile::tempdir().unwrap();
    write_reports(dir.path());
    let mut files = Vec::new();
    svgs(dir.path(), &mut files);
    files.sort();
    // The reproduction's figures, the plots of two sensitivity reports and
    // the search's marker views.
    assert!(files.len() >= 40, "only {} SVGs written", files.len());
    let mut found: Vec<String> = files.iter().flat_map(|f| problems(f)).collect();
    // Every report the runs wrote reads without placeholders.
    let mut reports = Vec::new();
    markdown_files(dir.path(), &mut reports);
    assert!(reports.len() >= 3, "only {} reports written", reports.len());
    for report in &reports {
        let text = std::fs::read_to_string(report).unwrap();
        found.extend(placeholders(&report.display().to_string(), &text));
    }
    assert!(
        found.is_empty(),
        "{} problems:\n{}",
        found.len(),
        found.join("\n")
    );

    // The depth plot labels its log axis below 1 and says where nothing is
    // visible; the availability panel is there.
    let depth = std::fs::read_to_string(dir.path().join("sensitivity/error_vs_depth.svg"))
        .unwrap_or_else(|e| panic!("error_vs_depth.svg: {e}; written: {files:?}"));
    let (_, depth_texts) = texts(&depth);
    assert!(depth_texts
        .iter()
        .any(|t| t.class == "tick-y" && t.content.parse::<f64>().is_ok_and(|v| v < 1.0)));
    assert!(depth_texts
        .iter()
        .any(|t| t.content.starts_with("nothing visible at depth 200")));
    assert!(depth_texts
        .iter()
        .any(|t| t.content == "share of scenarios with every sphere visible"));
}

#[test]
fn the_checker_catches_noise_overlap_and_clipping() {
    let svg = r#"<svg viewBox="0 0 100 50">
<text class="tick-x" x="40" y="20" font-size="10" text-anchor="end">0.30000000000000004</text>
<text class="tick-y" x="40" y="24" font-size="10" text-anchor="end">1000.0</text>
<text class="tick-y" x="40" y="40" font-size="10" text-anchor="end">100.0</text>
</svg>"#;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.svg");
    std::fs::write(&path, svg).unwrap();
    let found = problems(&path).join("\n");
    assert!(
        found.contains("'0.30000000000000004' leaves the view box"),
        "{found}"
    );
    assert!(found.contains("overlaps"), "{found}");
    assert!(found.contains("float noise"), "{found}");
    assert!(found.contains("'1000.0' has more decimals"), "{found}");
}

#[test]
fn style_and_placeholder_checks_catch_what_they_look_for() {
    let svg = r##"<svg viewBox="0 0 100 50">
<g class="legend-entry" data-legend="1" data-dash="2 3" data-marker="square"/>
<g class="legend-entry" data-legend="1" data-dash="2 3" data-marker="square"/>
<g class="legend-entry" data-legend="2" data-dash="solid" data-marker="circle"/>
<rect x="0" y="0" width="5" height="5" fill="#F8696B"/>
<rect x="0" y="0" width="5" height="5" fill="#63BE7B"/>
</svg>"##;
    let found = style_problems("bad.svg", svg).join("\n");
    assert!(found.contains("two series drawn with dash 2 3"), "{found}");
    assert!(found.contains("red against green"), "{found}");
    let crowded: String = (0..9)
        .map(|k| {
            format!(
                r#"<g class="legend-entry" data-legend="1" data-dash="{k}" data-marker="circle"/>"#
            )
        })
        .collect();
    assert!(style_problems("crowded.svg", &crowded)
        .join("\n")
        .contains("9 series in one panel"));
    // A sequential pale-to-dark scale and distinct styles pass.
    let good = r##"<rect fill="#FFFFD4"/><rect fill="#FE9929"/><rect fill="#993404"/>
<g class="legend-entry" data-legend="1" data-dash="solid" data-marker="circle"/>
<g class="legend-entry" data-legend="1" data-dash="solid" data-marker="square"/>"##;
    assert_eq!(style_problems("good.svg", good), Vec::<String>::new());

    let report = "on the objective ()\nrounds []\nE_rot 0.2–0.?°\n| a | ? |\nmean NaN\nfine (σ = 1) and [1, 2]";
    let found = placeholders("report.md", report);
    assert_eq!(found.len(), 5, "{found:?}");
}

#[test]
fn the_committed_solver_heatmaps_are_colour_blind_safe() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/solvers");
    let mut files = Vec::new();
    svgs(&dir, &mut files);
    assert!(!files.is_empty(), "no heatmaps in {}", dir.display());
    let found: Vec<String> = files
        .iter()
        .flat_map(|f| {
            style_problems(
                &f.display().to_string(),
                &std::fs::read_to_string(f).unwrap(),
            )
        })
        .collect();
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn the_front_plot_is_linear_padded_and_marks_the_winner() {
    use layout_opt::report::plots::{front_plot, FrontPlot, Series};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("front.svg");
    let point = |name: &str, x: f64, y: f64| Series {
        name: name.into(),
        points: vec![(x, y)],
        dashed: false,
    };
    let series = [
        Series {
            name: "Pareto front (search)".into(),
            points: vec![
                (55.6, 0.1988),
                (77.8, 0.1997),
                (88.9, 0.2021),
                (100.0, 0.2417),
            ],
            dashed: false,
        },
        point("paper-biprism", 68.9, 0.3631),
        point("seven-cube-corners", 60.0, 0.2023),
        point("tetrahedron-with-centre", 77.8, 0.2591),
    ];
    front_plot(
        &path,
        &FrontPlot {
            title: "front",
            x_label: "availability (%)",
            y_label: "RMS rotation (°)",
            series: &series,
            winner: Some(("biprism-search", (71.1, 0.2008))),
        },
    )
    .unwrap();
    assert_eq!(problems(&path), Vec::<String>::new());
    let svg = std::fs::read_to_string(&path).unwrap();
    let (_, all) = texts(&svg);
    // A linear y axis: its labelled ticks are evenly spaced.
    let mut ticks: Vec<f64> = all
        .iter()
        .filter(|t| t.class == "tick-y")
        .map(|t| t.content.parse().unwrap())
        .collect();
    ticks.sort_by(f64::total_cmp);
    assert!(ticks.len() >= 3, "{ticks:?}");
    let step = ticks[1] - ticks[0];
    assert!(
        ticks.windows(2).all(|w| (w[1] - w[0] - step).abs() < 1e-9),
        "y ticks not linear: {ticks:?}"
    );
    // The winner is named on the plot and in the legend; the better corner
    // is marked.
    for (class, content) in [
        ("point-label", "winner: biprism-search"),
        ("legend", "winner: biprism-search"),
        ("note", "better"),
    ] {
        assert!(
            all.iter().any(|t| t.class == class && t.content == content),
            "no {class} text {content:?}"
        );
    }
    // Every marker sits inside the frame, off its lines (the axes are
    // padded): the frame is the area's black rectangle.
    let frame = svg
        .split('<')
        .find(|t| t.starts_with("rect") && t.contains(r##"fill="none" stroke="#000000""##))
        .unwrap();
    let (left, top) = (number(frame, "x"), number(frame, "y"));
    let (right, bottom) = (left + number(frame, "width"), top + number(frame, "height"));
    let mut centres = Vec::new();
    for tag in svg.split('<') {
        if tag.starts_with("circle") && !tag.contains("class=") {
            centres.push((number(tag, "cx"), number(tag, "cy")));
        } else if tag.starts_with("polygon") && !tag.contains("class=") {
            let points: Vec<f64> = attribute(tag, "points")
                .unwrap()
                .split([' ', ','])
                .map(|v| v.parse().unwrap())
                .collect();
            let n = (points.len() / 2) as f64;
            let sum = |k: usize| points.iter().skip(k).step_by(2).sum::<f64>() / n;
            centres.push((sum(0), sum(1)));
        }
    }
    // The legend's markers stand to the right of the frame.
    centres.retain(|&(x, _)| x < right + 8.0);
    assert!(centres.len() >= 7, "{centres:?}");
    for (x, y) in centres {
        assert!(
            x > left + 5.0 && x < right - 5.0 && y > top + 5.0 && y < bottom - 5.0,
            "a marker at ({x}, {y}) sits on the frame ({left}, {top}, {right}, {bottom})"
        );
    }
}
