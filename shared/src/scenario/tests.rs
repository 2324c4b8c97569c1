//! One test per validation rule: each edits a built-in scenario and checks the
//! error names the field and gives the reason.

use super::*;

fn winding() -> String {
    builtin_text("winding-2d").expect("built-in").to_string()
}

/// Apply `edit` to winding-2d and expect an `Invalid` error on a field containing
/// `field` with a reason containing `reason`.
fn refused(text: &str, field: &str, reason: &str) {
    match Scenario::from_toml(text) {
        Err(ScenarioError::Invalid {
            field: f,
            reason: r,
        }) => {
            assert!(
                f.contains(field),
                "field `{f}` should name `{field}` (reason: {r})"
            );
            assert!(r.contains(reason), "reason `{r}` should contain `{reason}`");
        }
        other => panic!("expected Invalid({field}), got {other:?}"),
    }
}

fn replace_once(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture lacks {from:?}");
    text.replacen(from, to, 1)
}

#[test]
fn builtins_load_and_have_stable_hashes() {
    for name in BUILTIN_NAMES {
        let s = Scenario::builtin(name).expect("built-in is valid");
        assert_eq!(s.name, name);
        assert_eq!(s.content_hash.len(), 64);
        let again = Scenario::builtin(name).expect("valid");
        assert_eq!(s.content_hash, again.content_hash);
    }
    let w = Scenario::builtin("winding-2d").expect("valid");
    assert_eq!(
        (w.dim, w.sensors.len(), w.legs.len(), w.obstacles.len()),
        (2, 7, 11, 13)
    );
    assert_eq!(w.deltas.len(), 5);
    let s3 = Scenario::builtin("superg-3d").expect("valid");
    assert_eq!(s3.dim, 3);
}

#[test]
fn unknown_builtin_is_named() {
    assert_eq!(
        Scenario::builtin("windy").expect_err("must be refused"),
        ScenarioError::UnknownBuiltin("windy".into())
    );
}

#[test]
fn hash_changes_with_content() {
    let a = Scenario::from_toml(&winding()).expect("valid");
    let b = Scenario::from_toml(&replace_once(&winding(), "u_max = 0.05", "u_max = 0.06"))
        .expect("valid");
    assert_ne!(a.content_hash, b.content_hash);
}

#[test]
fn not_toml_is_a_parse_error() {
    assert!(matches!(
        Scenario::from_toml("dim = [").expect_err("must be refused"),
        ScenarioError::Parse(_)
    ));
    // Missing table.
    let t = winding().replace(
        "[controller]\nu_max = 0.05\neps_x = 0.05\nk_max = 200\n",
        "",
    );
    assert!(matches!(
        Scenario::from_toml(&t).expect_err("must be refused"),
        ScenarioError::Parse(_)
    ));
}

#[test]
fn unknown_sensor_in_leg() {
    let t = replace_once(
        &winding(),
        "to = [5.5, 1.0]\nsensor = \"s1\"",
        "to = [5.5, 1.0]\nsensor = \"s9\"",
    );
    refused(&t, "leg[1].sensor", "unknown sensor");
}

#[test]
fn matrix_of_wrong_shape() {
    let t = replace_once(
        &winding(),
        "F = [[1.0, 0.0], [0.0, 1.0]]",
        "F = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
    );
    refused(&t, "model.F", "");
    let t = replace_once(
        &winding(),
        "H = [[1.0, 0.0], [0.0, 1.0]]",
        "H = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
    );
    refused(&t, "sensor[0]", "");
    let t = replace_once(&winding(), "x0 = [0.5, 1.0]", "x0 = [0.5, 1.0, 2.0]");
    refused(&t, "model.x0", "");
}

#[test]
fn covariances_must_be_spd() {
    let t = replace_once(
        &winding(),
        "Q = [[0.0049, 0.0], [0.0, 0.0049]]",
        "Q = [[0.0049, 0.001], [0.0, 0.0049]]",
    );
    refused(&t, "model.Q", "symmetric");
    let t = replace_once(
        &winding(),
        "Q = [[0.0049, 0.0], [0.0, 0.0049]]",
        "Q = [[0.0049, 0.0], [0.0, -0.0049]]",
    );
    refused(&t, "model.Q", "positive definite");
    let t = replace_once(
        &winding(),
        "P0 = [[0.0009, 0.0], [0.0, 0.0009]]",
        "P0 = [[0.0009, 0.0], [0.0, 0.0]]",
    );
    refused(&t, "model.P0", "positive definite");
    let t = replace_once(
        &winding(),
        "R = [[0.0009, 0.0], [0.0, 0.0009]]",
        "R = [[0.0009, 0.5], [0.5, 0.0009]]",
    );
    refused(&t, "sensor[0]", "positive definite");
}

#[test]
fn nan_and_inf_are_refused() {
    let t = replace_once(&winding(), "x0 = [0.5, 1.0]", "x0 = [nan, 1.0]");
    refused(&t, "model.x0", "finite");
    let t = replace_once(
        &winding(),
        "F = [[1.0, 0.0], [0.0, 1.0]]",
        "F = [[1.0, inf], [0.0, 1.0]]",
    );
    refused(&t, "model.F", "finite");
    let t = replace_once(
        &winding(),
        "position = [1.75, 0.5]",
        "position = [1.75, -inf]",
    );
    refused(&t, "sensor[0]", "finite");
    let t = replace_once(&winding(), "u_max = 0.05", "u_max = nan");
    refused(&t, "controller.u_max", "");
}

#[test]
fn empty_route() {
    let text = winding();
    let start = text.find("[[leg]]").expect("legs");
    let end = text.find("[target]").expect("target");
    let t = format!("{}{}", &text[..start], &text[end..]);
    refused(&t, "leg", "empty");
}

#[test]
fn boxes_with_min_above_max() {
    let t = replace_once(&winding(), "min = [10.38, 6.88]", "min = [10.38, 7.5]");
    refused(&t, "target", "min");
    let t = replace_once(&winding(), "min = [5.45, 1.48]", "min = [5.6, 1.48]");
    refused(&t, "obstacle[0]", "min");
}

#[test]
fn start_inside_an_obstacle() {
    let t = replace_once(&winding(), "x0 = [0.5, 1.0]", "x0 = [1.6, 2.5]");
    refused(&t, "model.x0", "obstacle");
}

#[test]
fn thresholds_must_be_non_negative_and_distinct() {
    let t = replace_once(
        &winding(),
        "deltas = [0.0, 1.0518",
        "deltas = [-0.5, 1.0518",
    );
    refused(&t, "triggering.deltas", "");
    let t = replace_once(
        &winding(),
        "deltas = [0.0, 1.0518",
        "deltas = [1.0518, 1.0518",
    );
    refused(&t, "triggering.deltas", "duplicate");
    let t = replace_once(
        &winding(),
        "deltas = [0.0, 1.0518, 1.4986, 1.9488, 2.2365]",
        "deltas = []",
    );
    refused(&t, "triggering.deltas", "");
}

#[test]
fn duplicate_sensor_names() {
    let t = replace_once(&winding(), "name = \"s1\"", "name = \"s0\"");
    refused(&t, "sensor[1]", "duplicate");
}

#[test]
fn dimension_above_six() {
    let t = replace_once(&winding(), "dim = 2", "dim = 7");
    refused(&t, "dim", "");
    let t = replace_once(&winding(), "dim = 2", "dim = 0");
    refused(&t, "dim", "");
}

#[test]
fn controller_limits() {
    refused(
        &replace_once(&winding(), "eps_x = 0.05", "eps_x = 0.0"),
        "controller.eps_x",
        "",
    );
    refused(
        &replace_once(&winding(), "k_max = 200", "k_max = 0"),
        "controller.k_max",
        "",
    );
    refused(
        &replace_once(&winding(), "cost = 1.0", "cost = -1.0"),
        "sensor[0]",
        "",
    );
}
