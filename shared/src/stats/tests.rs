//! The statistics against closed forms and textbook values.
#[test]
fn a_ratio_by_the_delta_method() {
    let e = |value, ci95| super::Estimate { value, ci95 };
    let r = super::ratio(e(200.0, 6.0), e(100.0, 4.0)).expect("ratio");
    assert!((r.value - 2.0).abs() < 1e-12);
    assert!((r.ci95 - 2.0 * (0.03f64.powi(2) + 0.04f64.powi(2)).sqrt()).abs() < 1e-12);
    assert_eq!(
        super::ratio(e(1.0, 0.1), e(1.0, 0.0)).map(|r| r.ci95),
        Some(0.1)
    );
    assert!(super::ratio(e(1.0, 0.1), e(0.0, 0.1)).is_none());
}

use super::*;

#[test]
fn mean_of_constant_has_zero_width() {
    let mut a = MeanAccumulator::default();
    for _ in 0..10 {
        a.push(2.5);
    }
    let e = a.estimate();
    assert_eq!(e.value, 2.5);
    assert!(e.ci95.abs() < 1e-12);
}

#[test]
fn wilson_matches_textbook_value() {
    // 5 of 10: Wilson 95 % interval (0.2366, 0.7634).
    let (lo, hi) = wilson_interval(5, 10);
    assert!(
        (lo - 0.2366).abs() < 1e-4 && (hi - 0.7634).abs() < 1e-4,
        "{lo} {hi}"
    );
    let e = proportion(0, 100);
    assert_eq!(e.value, 0.0);
    assert!(e.ci95 > 0.03 && e.ci95 < 0.04, "{}", e.ci95);
}

#[test]
fn wilson_matches_newcombe_1998_table_1() {
    // Newcombe, Statistics in Medicine 17 (1998), Table I, method 3 (score,
    // no continuity correction), to the table's 4 decimals.
    for (k, n, lo, hi) in [
        (81, 263, 0.2553, 0.3662),
        (15, 148, 0.0624, 0.1605),
        (0, 20, 0.0, 0.1611),
        (1, 29, 0.0061, 0.1718),
    ] {
        let (l, h) = wilson_interval(k, n);
        assert!(
            (l - lo).abs() < 5e-5 && (h - hi).abs() < 5e-5,
            "{k}/{n}: {l} {h}"
        );
    }
    // The closed form's ends at 0 and n: z²/(n + z²) and n/(n + z²).
    let z2 = Z95 * Z95;
    assert_eq!(wilson_interval(0, 20).0, 0.0);
    assert!((wilson_interval(0, 20).1 - z2 / (20.0 + z2)).abs() < 1e-15);
    assert!((wilson_interval(10, 10).0 - 10.0 / (10.0 + z2)).abs() < 1e-15);
    assert_eq!(wilson_interval(10, 10).1, 1.0);
    assert_eq!(wilson_interval(0, 0), (0.0, 1.0));
}

#[test]
fn a_mean_needs_two_samples_for_an_interval() {
    let e = mean_of(&[1.0, 3.0]);
    assert_eq!(e.value, 2.0);
    assert!((e.ci95 - Z95 * (2.0f64 / 2.0).sqrt()).abs() < 1e-12);
    let one = mean_of(&[5.0]);
    assert_eq!(one.value, 5.0);
    assert!(one.ci95.is_infinite());
    assert!(mean_of(&[]).value.is_nan());
    assert!((z_two_sided(0.95) - Z95).abs() < 1e-12);
}

#[test]
fn ratio_of_proportional_sums_is_exact() {
    let mut r = RatioAccumulator::default();
    for b in [10.0, 20.0, 30.0] {
        r.push(0.25 * b, b);
    }
    let e = r.estimate();
    assert!((e.value - 0.25).abs() < 1e-12 && e.ci95 < 1e-9);
}
