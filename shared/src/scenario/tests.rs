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

/// A threshold or cost written as −0 is +0 from the start: the same value,
/// and one the recording's protobuf keeps bit for bit (proto3 drops zero
/// scalars, so a −0 would come back as +0).
#[test]
fn a_negative_zero_threshold_or_cost_is_plus_zero() {
    let t = replace_once(
        &winding(),
        "deltas = [0.0, 1.0518",
        "deltas = [-0.0, 1.0518",
    );
    let s = Scenario::from_toml(&t).expect("−0 is a threshold");
    assert_eq!(s.deltas[0].to_bits(), 0.0f64.to_bits());
    let cost = s.sensors[0].cost;
    let t = t.replacen(&format!("cost = {cost:?}"), "cost = -0.0", 1);
    let s = Scenario::from_toml(&t).expect("−0 is a cost");
    assert_eq!(s.sensors[0].cost.to_bits(), 0.0f64.to_bits());
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

// ---- MODEL.md §7: workspace map, n×p input, feedback gain -------------------

fn double_integrator() -> String {
    include_str!("../testdata/double-integrator.toml").to_string()
}

const LQR: &str = "[controller.lqr]\nstate = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.2, 0.0], [0.0, 0.0, 0.0, 0.2]]\ninput = [[0.5, 0.0], [0.0, 0.5]]\n";

#[test]
fn double_integrator_loads_with_an_lqr_gain() {
    let s = Scenario::from_toml(&double_integrator()).expect("valid");
    assert_eq!((s.dim, s.workspace_dim(), s.input_dim()), (4, 2, 2));
    let k = s.gain.as_ref().expect("K from the DARE");
    assert_eq!((k.nrows(), k.ncols()), (2, 4));
    let rho = crate::lqr::spectral_radius(&(&s.plant.f - &s.plant.g * k));
    assert!(rho < 1.0);
    assert_eq!(s.route_start.as_slice(), &[0.0, 0.0]);
    assert_eq!(s.leg_start(0).as_slice(), &[0.0, 0.0]);
    assert_eq!(s.reference(&s.legs[0].to).as_slice(), &[2.0, 0.0, 0.0, 0.0]);
    assert_eq!(
        s.workspace_point(&[1.0, 2.0, 3.0, 4.0]).as_slice(),
        &[1.0, 2.0]
    );
}

#[test]
fn absent_fields_keep_the_paper_model_and_its_hash() {
    // The content hash of a scenario without the §7 fields is computed as
    // before §7 (new fields are not serialised when absent): this is the hash
    // winding-2d had before, so existing strategies and recordings still match.
    let raw: raw::RawScenario = toml::from_str(&winding()).expect("toml");
    let canonical = serde_json::to_string(&raw).expect("json");
    for key in ["\"C\"", "\"K\"", "\"lqr\""] {
        assert!(!canonical.contains(key), "{key} serialised when absent");
    }
    let w = Scenario::builtin("winding-2d").expect("valid");
    assert!(w.workspace.is_none() && w.gain.is_none() && w.warnings.is_empty());
    assert_eq!(w.route_start, w.plant.x0);
    assert_eq!((w.workspace_dim(), w.input_dim()), (2, 2));
}

#[test]
fn workspace_map_shape_and_rank() {
    let t = replace_once(
        &double_integrator(),
        "C = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]",
        "C = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
    );
    refused(&t, "model.C", "shape");
    let t = replace_once(
        &double_integrator(),
        "C = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]",
        "C = [[1.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0]]",
    );
    refused(&t, "model.C", "full row rank");
    let t = replace_once(
        &double_integrator(),
        "C = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]",
        "C = []",
    );
    refused(&t, "model.C", "1 <= d");
}

#[test]
fn points_and_boxes_live_in_the_workspace() {
    let t = replace_once(
        &double_integrator(),
        "to = [2.0, 0.0]",
        "to = [2.0, 0.0, 0.0, 0.0]",
    );
    refused(&t, "leg[0].to", "2 entries");
    let t = replace_once(
        &double_integrator(),
        "position = [0.0, 0.0]",
        "position = [0.0, 0.0, 0.0]",
    );
    refused(&t, "sensor[0] \"a\".position", "workspace point");
    let t = replace_once(
        &double_integrator(),
        "min = [1.8, 1.8]",
        "min = [1.8, 1.8, 0.0, 0.0]",
    );
    refused(&t, "target.min", "");
    let t = replace_once(&double_integrator(), "min = [2.12, -1.0]", "min = [2.12]");
    refused(&t, "obstacle[0]", "");
    // x0 stays in R^n; the start is judged on C x0.
    let t = replace_once(
        &double_integrator(),
        "x0 = [0.0, 0.0, 0.0, 0.0]",
        "x0 = [2.2, 0.0, 0.0, 0.0]",
    );
    refused(&t, "model.x0", "obstacle");
}

#[test]
fn input_matrix_and_gain_shapes() {
    let t = replace_once(
        &double_integrator(),
        "G = [[0.005, 0.0], [0.0, 0.005], [0.1, 0.0], [0.0, 0.1]]",
        "G = [[0.005, 0.0, 0.0, 0.0, 0.0], [0.0, 0.005, 0.0, 0.0, 0.0], [0.1, 0.0, 0.0, 0.0, 0.0], [0.0, 0.1, 0.0, 0.0, 0.0]]",
    );
    refused(&t, "model.G", "1 <= p <= n");
    let t = replace_once(
        &double_integrator(),
        "G = [[0.005, 0.0], [0.0, 0.005], [0.1, 0.0], [0.0, 0.1]]",
        "G = [[0.005, 0.0], [0.0, 0.005], [0.1, 0.0], [0.0]]",
    );
    refused(&t, "model.G", "shape");
    // p ≠ n without a gain.
    let t = replace_once(&double_integrator(), LQR, "");
    refused(&t, "controller.K", "p = 2");
    // Both a gain and LQR weights.
    let t = replace_once(
        &double_integrator(),
        "k_max = 150\n",
        "k_max = 150\nK = [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0]]\n",
    );
    refused(&t, "controller.K", "not both");
    // A gain of the wrong shape (n×n instead of p×n).
    let t = replace_once(
        &double_integrator(),
        LQR,
        "",
    )
    .replace("k_max = 150\n", "k_max = 150\nK = [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n");
    refused(&t, "controller.K", "shape");
    // A given gain of the right shape is taken as is.
    let t = replace_once(&double_integrator(), LQR, "").replace(
        "k_max = 150\n",
        "k_max = 150\nK = [[1.0, 0.0, 1.5, 0.0], [0.0, 1.0, 0.0, 1.5]]\n",
    );
    let s = Scenario::from_toml(&t).expect("valid");
    assert_eq!(s.gain.as_ref().map(|k| k[(0, 2)]), Some(1.5));
}

#[test]
fn lqr_weights_are_checked_and_a_missing_solution_is_named() {
    let t = replace_once(
        &double_integrator(),
        "input = [[0.5, 0.0], [0.0, 0.5]]",
        "input = [[0.5, 0.0], [0.0, 0.0]]",
    );
    refused(&t, "controller.lqr.input", "positive definite");
    let t = replace_once(
        &double_integrator(),
        "state = [[1.0, 0.0, 0.0, 0.0]",
        "state = [[-1.0, 0.0, 0.0, 0.0]",
    );
    refused(&t, "controller.lqr.state", "semi-definite");
    // The input cannot reach the y axis (G's second column zero) and y is
    // unstable (F_yy = 1.1): no stabilising solution.
    let t = replace_once(
        &double_integrator(),
        "G = [[0.005, 0.0], [0.0, 0.005], [0.1, 0.0], [0.0, 0.1]]",
        "G = [[0.005, 0.0], [0.0, 0.0], [0.1, 0.0], [0.0, 0.0]]",
    )
    .replace(
        "F = [[1.0, 0.0, 0.1, 0.0], [0.0, 1.0, 0.0, 0.1]",
        "F = [[1.0, 0.0, 0.1, 0.0], [0.0, 1.1, 0.0, 0.1]",
    );
    refused(&t, "controller.lqr", "stabilising");
    // Weights that ignore an unstable mode: the DARE has a solution (S = 0 on
    // that mode) but the closed loop is unstable.
    let t = replace_once(
        &double_integrator(),
        "F = [[1.0, 0.0, 0.1, 0.0], [0.0, 1.0, 0.0, 0.1], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
        "F = [[1.0, 0.0, 0.1, 0.0], [0.0, 1.0, 0.0, 0.1], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.2]]",
    )
    .replace(
        "state = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.2, 0.0], [0.0, 0.0, 0.0, 0.2]]",
        "state = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.2, 0.0], [0.0, 0.0, 0.0, 0.0]]",
    );
    refused(&t, "controller.lqr", "");
}

#[test]
fn a_reference_that_is_not_a_rest_point_is_warned_about() {
    // A damped velocity (F_vv = 0.9) is still a rest point at zero velocity...
    let t = replace_once(
        &double_integrator(),
        "[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
        "[0.0, 0.0, 0.9, 0.0], [0.0, 0.0, 0.0, 0.9]]",
    );
    assert!(Scenario::from_toml(&t).expect("valid").warnings.is_empty());
    // ... a position that decays (F_xx = 0.99) is not.
    let t = replace_once(
        &double_integrator(),
        "F = [[1.0, 0.0, 0.1, 0.0]",
        "F = [[0.99, 0.0, 0.1, 0.0]",
    );
    let s = Scenario::from_toml(&t).expect("valid, with a warning");
    assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
    assert!(s.warnings[0].contains("leg[0].to") && s.warnings[0].contains("rest point"));
}

#[test]
fn a_trigger_family_is_read_box_said_aloud_keeps_the_hash_and_text_can_carry_one() {
    use crate::scenario::ScenarioText;
    use crate::trigger::TriggerFamily;
    let plain = Scenario::builtin("winding-2d").expect("valid");
    assert_eq!(plain.trigger, TriggerFamily::Box);
    let with = |family: &str| {
        replace_once(
            &winding(),
            "[triggering]",
            &format!("[triggering]\nfamily = \"{family}\""),
        )
    };
    let boxed = Scenario::from_toml(&with("box")).expect("valid");
    assert_eq!(boxed.content_hash, plain.content_hash);
    let stochastic = Scenario::from_toml(&with("stochastic")).expect("valid");
    assert_eq!(stochastic.trigger, TriggerFamily::Stochastic);
    assert_ne!(stochastic.content_hash, plain.content_hash);
    let e = Scenario::from_toml(&with("often")).expect_err("unknown family");
    assert!(e.to_string().contains("triggering.family"), "{e}");
    // `--trigger`: the text rewritten to carry the family, and back.
    let own = ScenarioText::parse(winding()).expect("valid");
    let sod = own
        .with_trigger(TriggerFamily::SendOnDelta)
        .expect("written");
    assert_eq!(sod.scenario.trigger, TriggerFamily::SendOnDelta);
    let back = sod.with_trigger(TriggerFamily::Box).expect("written");
    assert_eq!(back.scenario.content_hash, plain.content_hash);
}
