//! Scenarios whose fields are well formed but that cannot work
//! (docs/MODEL.md §1.1): each is refused naming the field; the near misses
//! on the other side of each criterion load.

use super::*;

fn winding() -> String {
    builtin_text("winding-2d").expect("built-in").to_string()
}

fn double_integrator() -> String {
    include_str!("../testdata/double-integrator.toml").to_string()
}

fn replace_once(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture lacks {from:?}");
    text.replacen(from, to, 1)
}

/// The `Invalid` error of a refused text: (field, reason).
fn refusal(text: &str) -> (String, String) {
    match Scenario::from_toml(text) {
        Err(ScenarioError::Invalid { field, reason }) => (field, reason),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

/// winding-2d with every sensor's H and R replaced.
fn winding_sensors(h: &str, r: &str) -> String {
    winding()
        .replace("H = [[1.0, 0.0], [0.0, 1.0]]", &format!("H = {h}"))
        .replace("R = [[0.0009, 0.0], [0.0, 0.0009]]", &format!("R = {r}"))
}

#[test]
fn a_state_growing_a_million_times_a_step_is_refused_on_model_f() {
    let t = replace_once(
        &winding(),
        "F = [[1.0, 0.0], [0.0, 1.0]]",
        "F = [[1e6, 0.0], [0.0, 1.0]]",
    );
    let (field, reason) = refusal(&t);
    assert_eq!(field, "model.F");
    // One step multiplies a covariance by 1e12 (inside f64's 4.5e12), two by 1e24.
    assert!(
        reason.contains("horizon") && reason.contains("‖F^2‖"),
        "{reason}"
    );
}

#[test]
fn growth_is_judged_over_the_longest_episode() {
    // winding-2d: 11 legs × k_max 200 = 2200 steps. 1.0001^2200 ≈ 1.25
    // (accepted), 1.01^2200 ≈ 3e9 > √(1e-3/ε) ≈ 2.1e6 (refused).
    let with_f = |f: &str| {
        replace_once(
            &winding(),
            "F = [[1.0, 0.0], [0.0, 1.0]]",
            &format!("F = [[{f}, 0.0], [0.0, {f}]]"),
        )
    };
    Scenario::from_toml(&with_f("1.0001")).expect("mild growth loads");
    let (field, reason) = refusal(&with_f("1.01"));
    assert_eq!(field, "model.F");
    assert!(reason.contains("2200 steps"), "{reason}");
    // Past the steps measured one by one, the powers of two and the horizon
    // decide: k_max 10⁶ (11·10⁶ steps) with F = I loads, with 1.000002
    // (e^22 ≈ 3.6e9 over the horizon) it is refused.
    let long = |f: &str| replace_once(&with_f(f), "k_max = 200", "k_max = 1000000");
    Scenario::from_toml(&long("1.0")).expect("F = I never grows");
    let (field, reason) = refusal(&long("1.000002"));
    assert_eq!(field, "model.F");
    assert!(reason.contains("11000000 steps"), "{reason}");
    // A non-normal F whose powers die out can still grow too much on the way.
    let t = replace_once(
        &winding(),
        "F = [[1.0, 0.0], [0.0, 1.0]]",
        "F = [[0.5, 1e7], [0.0, 0.5]]",
    );
    assert_eq!(refusal(&t).0, "model.F");
}

#[test]
fn a_direction_no_sensor_measures_is_refused_on_the_sensors_h() {
    // Every sensor sees x only: y is never measured and F = I keeps it.
    let t = winding_sensors("[[1.0, 0.0]]", "[[0.0009]]");
    let (field, reason) = refusal(&t);
    assert!(
        field.starts_with("sensor[0] \"s0\".H, sensor[1]"),
        "{field}"
    );
    assert!(
        reason.contains("rank 1 < n")
            && reason.contains("(0.000, 1.000)")
            && reason.contains("not detectable"),
        "{reason}"
    );
    // A rank-deficient H stacked twice is no better.
    let t = winding_sensors("[[1.0, 0.0], [2.0, 0.0]]", "[[0.0009, 0.0], [0.0, 0.0009]]");
    assert!(refusal(&t).1.contains("not detectable"));
    // Velocity-only sensors on a double integrator: the position is never
    // learned (F carries it, unobserved, with modulus 1).
    let t = double_integrator().replace(
        "H = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]",
        "H = [[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
    );
    let (field, reason) = refusal(&t);
    assert_eq!(field, "sensor[0] \"a\".H, sensor[1] \"b\".H");
    assert!(reason.contains("rank 2 < n"), "{reason}");
}

#[test]
fn a_rank_deficient_h_is_accepted_when_another_sensor_observes_the_rest() {
    // s0 sees only x; every other sensor sees only y: together they see both.
    let t = winding_sensors("[[0.0, 1.0]]", "[[0.0009]]").replacen(
        "H = [[0.0, 1.0]]",
        "H = [[1.0, 0.0]]",
        1,
    );
    let s = Scenario::from_toml(&t).expect("observable by the sensors together");
    assert_eq!(s.sensors[0].h.nrows(), 1);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Position-only sensors observe a double integrator's velocity through F.
    Scenario::from_toml(&double_integrator()).expect("observable through the dynamics");
}

#[test]
fn a_sensor_serving_no_leg_observes_nothing() {
    // winding-2d's s6 serves the last leg only; give every other sensor x only
    // and s6 the full H, then take s6 off its legs: y is never measured.
    let s = Scenario::builtin("winding-2d").expect("valid");
    let last = &s.sensors[s.legs[s.num_legs() - 1].sensor].name;
    let t = winding_sensors("[[1.0, 0.0]]", "[[0.0009]]");
    let mut parts: Vec<String> = t.split("[[sensor]]").map(str::to_string).collect();
    let i = parts
        .iter()
        .position(|p| p.contains(&format!("name = \"{last}\"")))
        .expect("the last leg's sensor");
    parts[i] = parts[i]
        .replace("H = [[1.0, 0.0]]", "H = [[1.0, 0.0], [0.0, 1.0]]")
        .replace("R = [[0.0009]]", "R = [[0.0009, 0.0], [0.0, 0.0009]]");
    let served = parts.join("[[sensor]]");
    Scenario::from_toml(&served).expect("the last legs' sensor measures y");
    let unserved = served.replace(
        &format!("sensor = \"{last}\""),
        &format!("sensor = \"{}\"", s.sensors[0].name),
    );
    let (field, _) = refusal(&unserved);
    assert!(!field.contains(&format!("\"{last}\"")), "{field}");
}

#[test]
fn an_unobserved_direction_that_decays_is_a_warning() {
    // y is never measured but F halves it every step: the filter's
    // uncertainty there settles (detectable); `etp check` says so.
    let t = replace_once(
        &winding_sensors("[[1.0, 0.0]]", "[[0.0009]]"),
        "F = [[1.0, 0.0], [0.0, 1.0]]",
        "F = [[1.0, 0.0], [0.0, 0.5]]",
    );
    let s = Scenario::from_toml(&t).expect("detectable");
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("decays by itself"),
        "{}",
        s.warnings[0]
    );
}

#[test]
fn a_controller_that_cannot_move_is_refused_on_u_max() {
    let t = replace_once(&winding(), "u_max = 0.05", "u_max = 1e-12");
    let (field, reason) = refusal(&t);
    assert_eq!(field, "controller.u_max");
    assert!(
        reason.contains("leg[") && reason.contains("k_max = 200"),
        "{reason}"
    );
    // winding-2d's longest leg is 4.61 long, eps_x 0.05: 200 steps of 0.0227
    // reach 4.54 (refused), of 0.0229 reach 4.58 (accepted).
    assert!(
        refusal(&replace_once(&winding(), "u_max = 0.05", "u_max = 0.0227"))
            .1
            .contains("] is 4.610 long")
    );
    Scenario::from_toml(&replace_once(&winding(), "u_max = 0.05", "u_max = 0.0229"))
        .expect("reaches every waypoint");
    // A double integrator's reach adds up through F: u_max 2e-3 moves it by
    // τ² Σ (j + ½) u_max = 0.01 · 150²/2 · 2e-3 = 0.225 in 150 steps.
    let t = replace_once(&double_integrator(), "u_max = 2.0", "u_max = 2e-3");
    assert_eq!(refusal(&t).0, "controller.u_max");
    let t = replace_once(&double_integrator(), "u_max = 2.0", "u_max = 0.2");
    Scenario::from_toml(&t).expect("0.2 · 112.5 = 22.5 covers the 2-long legs");
}

#[test]
fn numerically_singular_noise_is_refused() {
    for (from, to, field) in [
        (
            "Q = [[0.0049, 0.0], [0.0, 0.0049]]",
            "Q = [[0.0049, 0.0], [0.0, 1e-20]]",
            "model.Q",
        ),
        (
            "P0 = [[0.0009, 0.0], [0.0, 0.0009]]",
            "P0 = [[0.0009, 0.0], [0.0, 1e-17]]",
            "model.P0",
        ),
        (
            "R = [[0.0009, 0.0], [0.0, 0.0009]]",
            "R = [[0.0009, 0.0], [0.0, 1e-19]]",
            "sensor[0] \"s0\".R",
        ),
    ] {
        let (f, reason) = refusal(&replace_once(&winding(), from, to));
        assert_eq!(f, field);
        assert!(reason.contains("numerically singular"), "{reason}");
    }
    // Anisotropic but well conditioned (10⁸) loads.
    Scenario::from_toml(&replace_once(
        &winding(),
        "Q = [[0.0049, 0.0], [0.0, 0.0049]]",
        "Q = [[0.0049, 0.0], [0.0, 4.9e-11]]",
    ))
    .expect("condition 1e8");
}
