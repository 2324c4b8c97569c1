//! The reference scenarios, embedded so `etp` runs with no files at hand.

/// The default scenario of `etp demo`.
pub const DEFAULT_SCENARIO: &str = "winding-2d";

/// Names of the built-in scenarios.
pub const BUILTIN_NAMES: [&str; 3] = ["winding-2d", "open-2d", "superg-3d"];

/// The TOML text of a built-in scenario.
pub fn builtin_text(name: &str) -> Option<&'static str> {
    match name {
        "winding-2d" => Some(include_str!("../../../scenarios/winding-2d.toml")),
        "open-2d" => Some(include_str!("../../../scenarios/open-2d.toml")),
        "superg-3d" => Some(include_str!("../../../scenarios/superg-3d.toml")),
        _ => None,
    }
}
