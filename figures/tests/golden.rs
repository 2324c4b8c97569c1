//! Golden images: every figure kind drawn from fixed, small input (no
//! randomness, no clock) and compared with its committed PNG in
//! `tests/golden/`, both reduced to a quarter of their size (4 × 4 pixel
//! means, 16 levels a channel: the goldens stay a few tens of KB). The font is embedded and
//! rasterised by plotters itself, so the pixels barely move between
//! machines; the comparison still allows 0.02 % of the reduced pixels to
//! differ (by more than 40 of 255 in a channel), which a changed colour,
//! line, label or layout exceeds.
//!
//! On a mismatch the new image is written beside the golden one as
//! `KIND.actual.png` for inspection. After a deliberate change, look at
//! the new images and regenerate the goldens with
//! `ETP_UPDATE_GOLDEN=1 cargo test --release -p etp-figures --test golden`.
//!
//! The SVG of each figure is read too: its text sizes (readable with each
//! panel printed a column wide) and the units its axes name.

use etp_figures::{Bar, Curve, FamilySeries, Panel, PredictedMark, RatePoint, RunFigure};
use etp_shared::episode::Outcome;
use etp_shared::scenario::Scenario;
use etp_synthesis::validate::{Trajectory, TrajectoryPoint};
use std::path::{Path, PathBuf};

/// Differing pixels allowed, as a fraction of the image.
const MAX_DIFFERING: f64 = 0.0002;
/// A pixel differs when a channel moved by more than this.
const CHANNEL: i16 = 40;

fn out_dir(kind: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("golden")
        .join(kind);
    std::fs::create_dir_all(&dir).expect("a folder under the target dir");
    dir
}

/// Side of the blocks an image is reduced by.
const BLOCK: u32 = 4;

/// The image reduced to a quarter of its size, each pixel the mean of a
/// 4 × 4 block, its channels rounded to 16 levels (what keeps the goldens
/// small; a channel must move by 40 to count).
fn reduce(img: &image::RgbImage) -> image::RgbImage {
    let (w, h) = (img.width() / BLOCK, img.height() / BLOCK);
    image::RgbImage::from_fn(w, h, |x, y| {
        let mut sum = [0u32; 3];
        for dy in 0..BLOCK {
            for dx in 0..BLOCK {
                let p = img.get_pixel(BLOCK * x + dx, BLOCK * y + dy);
                for (s, v) in sum.iter_mut().zip(p.0) {
                    *s += u32::from(v);
                }
            }
        }
        image::Rgb(sum.map(|v| ((v / (BLOCK * BLOCK)) as u8 & 0xF0) | 0x08))
    })
}

/// Write `img` as a PNG compressed as far as the encoder goes.
fn save(img: &image::RgbImage, path: &Path) {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let file = std::fs::File::create(path).expect("golden created");
    PngEncoder::new_with_quality(file, CompressionType::Best, FilterType::Adaptive)
        .write_image(img, img.width(), img.height(), image::ColorType::Rgb8)
        .expect("golden written");
}

/// The fraction of pixels of `a` and `b` that differ; `None` when their
/// sizes differ.
fn differing(a: &image::RgbImage, b: &image::RgbImage) -> Option<f64> {
    if a.dimensions() != b.dimensions() {
        return None;
    }
    let n = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| {
            p.0.iter()
                .zip(q.0.iter())
                .any(|(x, y)| (i16::from(*x) - i16::from(*y)).abs() > CHANNEL)
        })
        .count();
    Some(n as f64 / f64::from(a.width() * a.height()))
}

/// Draw figure `kind` with `draw` (given the stem) and compare its PNG with
/// the golden one; the SVG's text, returned.
fn golden(kind: &str, draw: impl FnOnce(&Path)) -> String {
    let stem = out_dir(kind).join(kind);
    draw(&stem);
    let png = stem.with_extension("png");
    let golden_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let golden = golden_dir.join(format!("{kind}.png"));
    let new = reduce(&image::open(&png).expect("the drawn PNG").to_rgb8());
    if std::env::var("ETP_UPDATE_GOLDEN").is_ok_and(|v| v == "1") {
        save(&new, &golden);
    } else {
        let old = image::open(&golden)
            .unwrap_or_else(|e| panic!("{}: {e} (ETP_UPDATE_GOLDEN=1 writes it)", golden.display()))
            .to_rgb8();
        let diff = differing(&new, &old);
        if diff.is_none_or(|d| d > MAX_DIFFERING) {
            let actual = golden_dir.join(format!("{kind}.actual.png"));
            let _ = std::fs::copy(&png, &actual);
            panic!(
                "{kind}: {} from {} (allowed {MAX_DIFFERING}); the new image is {}; \
                 if the change is meant, ETP_UPDATE_GOLDEN=1 regenerates the goldens",
                diff.map_or("another size".to_string(), |d| format!(
                    "{d:.5} of the pixels differ"
                )),
                golden.display(),
                actual.display()
            );
        }
    }
    std::fs::read_to_string(stem.with_extension("svg")).expect("the drawn SVG")
}

/// The font sizes (pixels) of an SVG's text.
fn font_sizes(svg: &str) -> Vec<f64> {
    svg.split("font-size=\"")
        .skip(1)
        .filter_map(|s| s.split('"').next()?.parse().ok())
        .collect()
}

/// The smallest text is at least 1/50 of a panel's width: 5 pt or more
/// with the panel printed 3.5 in (252 pt) wide.
fn assert_readable(kind: &str, svg: &str, panel_width: f64) {
    let sizes = font_sizes(svg);
    assert!(!sizes.is_empty(), "{kind}: no text");
    let smallest = sizes.iter().copied().fold(f64::INFINITY, f64::min);
    let pt = smallest / panel_width * 252.0;
    assert!(
        pt >= 5.0,
        "{kind}: smallest text {smallest} px is {pt:.1} pt at column width"
    );
}

fn assert_says(kind: &str, svg: &str, words: &[&str]) {
    for w in words {
        assert!(svg.contains(w), "{kind}: no \"{w}\" in the figure");
    }
}

/// Golden `kind` drawn by `draw`, readable with each panel `panel_width`
/// pixels wide, naming `words`: its SVG.
fn check(kind: &str, panel_width: f64, words: &[&str], draw: impl FnOnce(&Path)) -> String {
    let svg = golden(kind, draw);
    assert_readable(kind, &svg, panel_width);
    assert_says(kind, &svg, words);
    svg
}

#[test]
fn front() {
    let text = include_str!("data/front-winding-2d.json");
    let front = serde_json::from_str(text).expect("the fixture is a front.json");
    check(
        "front",
        880.0,
        &[
            "expected energy per episode (transmissions × cost)",
            "P_tar (probability",
            "δ = 1.0518",
        ],
        |stem| etp_figures::front_plot(&front, stem).expect("drawn"),
    );
}

/// Five syntheses of growing energy, each with a certified curve; the
/// first with a predicted front.
fn fronts_panels() -> Vec<Panel> {
    [Some(0.05), None]
        .into_iter()
        .enumerate()
        .map(|(k, max_collision)| Panel {
            max_collision,
            curves: (0..5)
                .map(|i| {
                    let scale = 40.0 * (1.0 + 0.35 * i as f64) * (1.0 - 0.1 * k as f64);
                    let points: Vec<(f64, f64)> = (0..12)
                        .map(|j| {
                            let t = 0.6 + 0.035 * j as f64;
                            (t, scale * (1.0 + 3.0 * (t - 0.6).powi(2) / 0.15))
                        })
                        .collect();
                    let certified = points.iter().map(|&(t, e)| (t - 0.02, e * 1.08)).collect();
                    let predicted = if i == 0 {
                        [0.7, 0.85]
                            .iter()
                            .map(|&t| PredictedMark {
                                p_target: t,
                                energy: scale * (1.0 + 3.0 * (t - 0.6f64).powi(2) / 0.15),
                                p_target_ci95: 0.012,
                                energy_ci95: 4.0,
                                met: t < 0.8,
                            })
                            .collect()
                    } else {
                        Vec::new()
                    };
                    Curve {
                        dir: PathBuf::from(format!("syn-{i}")),
                        label: ["box", "stochastic", "send-on-delta", "variance", "periodic"][i]
                            .to_string(),
                        points,
                        certified,
                        predicted,
                    }
                })
                .collect(),
        })
        .collect()
}

#[test]
fn fronts() {
    let panels = fronts_panels();
    check(
        "fronts",
        820.0,
        &[
            "P_tar (probability",
            "least energy per episode (attempts × cost)",
        ],
        |stem| {
            etp_figures::fronts_plot("winding-2d", "trigger families", &panels, stem)
                .expect("drawn")
        },
    );
}

/// Five families at four thresholds; variance sends every slot at each.
fn families() -> Vec<FamilySeries> {
    let deltas = [1.0518, 1.4986, 1.9488, 2.2365];
    let family = |name: &str, rate: &dyn Fn(f64) -> f64| FamilySeries {
        name: name.to_string(),
        points: deltas
            .iter()
            .map(|&d| {
                let r = rate(d);
                RatePoint {
                    delta: d,
                    rate: (r, 0.004),
                    rmse: (0.02 + 0.03 * (1.0 - r), 0.001),
                    nees: (1.0 + 0.2 * (1.0 - r) * d / 2.0, 0.01),
                }
            })
            .collect(),
        closed_form: (0..=40)
            .map(|k| {
                let d = 1.0 + 1.3 * f64::from(k) / 40.0;
                (d, rate(d))
            })
            .collect(),
    };
    vec![
        family("box", &|d| (-0.9 * d).exp()),
        family("stochastic", &|d| (-0.7 * d).exp()),
        family("send-on-delta", &|d| 0.9 - 0.1 * d),
        family("variance", &|_| 1.0),
        family("periodic", &|d| (-0.9 * d).exp() + 0.01),
    ]
}

#[test]
fn trigger_curves() {
    let series = families();
    let svg = check(
        "trigger-curves",
        600.0,
        &[
            "Note: variance sends at rate 1.0000 at every δ",
            "rate (transmissions per slot)",
            "RMSE ‖x − x̂‖ (scenario units)",
            "threshold δ (noise standard deviations)",
        ],
        |stem| etp_figures::trigger_curves_plot("winding-2d", &series, stem).expect("drawn"),
    );
    // A family that is not degenerate gets no note.
    assert!(!svg.contains("Note: box"));
}

/// Sampled episodes along the route, deterministic: each offset to its
/// own side, the rate rising and falling along it; every fourth collides
/// half way.
fn trajectories(scenario: &Scenario) -> Vec<Trajectory> {
    let mut route = vec![scenario.route_start.as_slice().to_vec()];
    route.extend(scenario.legs.iter().map(|l| l.to.as_slice().to_vec()));
    (0..12)
        .map(|k| {
            let off = 0.06 * (f64::from(k) - 5.5);
            let collides = k % 4 == 1;
            let mut points = Vec::new();
            let legs = if collides {
                route.len() / 2
            } else {
                route.len() - 1
            };
            for (i, w) in route.windows(2).take(legs).enumerate() {
                for s in 0..10 {
                    let t = f64::from(s) / 10.0;
                    let x: Vec<f64> = w[0]
                        .iter()
                        .zip(&w[1])
                        .map(|(a, b)| a + t * (b - a) + off)
                        .collect();
                    let phase = (i as f64 + t) / (route.len() - 1) as f64;
                    points.push(TrajectoryPoint {
                        mean: x.clone(),
                        x,
                        expected_rate: (phase * std::f64::consts::PI * 2.0).sin().abs(),
                        transmitted: s % 3 == 0,
                    });
                }
            }
            Trajectory {
                points,
                outcome: if collides {
                    Outcome::Collision
                } else {
                    Outcome::Target
                },
            }
        })
        .collect()
}

/// The map of built-in `scenario` as golden `kind`, each panel
/// `panel_width` pixels wide, naming `words`.
fn map_of(scenario: &str, kind: &str, panel_width: f64, words: &[&str]) {
    let scenario = Scenario::builtin(scenario).expect("a built-in scenario");
    let tr = trajectories(&scenario);
    check(kind, panel_width, words, |stem| {
        etp_figures::map_plot(&scenario, &tr, stem).expect("drawn")
    });
}

#[test]
fn map() {
    let words = [
        "x1 (scenario units)",
        "x2 (scenario units)",
        "per slot",
        "collision",
    ];
    map_of("winding-2d", "map", 880.0, &words);
}

#[test]
fn map_3d() {
    let words = ["top view", "side view", "(scenario units)"];
    map_of("superg-3d", "map-3d", 800.0, &words);
}

fn bar(name: &str, measured: f64, half: f64, predicted: f64) -> Bar {
    Bar {
        name: name.to_string(),
        measured,
        interval: Some((measured - half, measured + half)),
        predicted: Some(predicted),
    }
}

#[test]
fn report() {
    // s0–s3 send about 3 packets per episode, s4 about 42: a log axis.
    let fig = RunFigure {
        title: "run r1 · winding-2d · constant δ = 1.4986 · 400 episodes".into(),
        prediction_note: "the synthesis's MDP (selection-time)".into(),
        sensors: vec![
            bar("s0", 3.1, 0.3, 3.0),
            bar("s1", 2.8, 0.3, 2.9),
            bar("s2", 3.4, 0.4, 3.2),
            bar("s3", 2.6, 0.2, 2.7),
            bar("s4", 42.0, 2.5, 41.0),
        ],
        outcomes: vec![
            bar("P_tar", 0.91, 0.03, 0.92),
            bar("P_coll", 0.05, 0.02, 0.05),
            bar("P_free", 0.04, 0.02, 0.03),
        ],
    };
    check(
        "report",
        720.0,
        &[
            "energy per episode (transmissions × cost), log scale",
            "probability (fraction of episodes)",
        ],
        |stem| etp_figures::report_plot(&fig, stem).expect("drawn"),
    );
}
