//! The reference scenarios, embedded so `etp` runs with no files at hand.

/// The default scenario of `etp demo`.
pub const DEFAULT_SCENARIO: &str = "winding-2d";

/// Names of the built-in scenarios.
pub const BUILTIN_NAMES: [&str; 5] = [
    "winding-2d",
    "open-2d",
    "superg-3d",
    "inertia-2d",
    "inertia-3d",
];

/// The TOML text of a built-in scenario.
pub fn builtin_text(name: &str) -> Option<&'static str> {
    match name {
        "winding-2d" => Some(include_str!("../../../scenarios/winding-2d.toml")),
        "open-2d" => Some(include_str!("../../../scenarios/open-2d.toml")),
        "superg-3d" => Some(include_str!("../../../scenarios/superg-3d.toml")),
        // MODEL.md §7: double integrators (n = 4, d = 2 and n = 6, d = 3).
        "inertia-2d" => Some(include_str!("../../../scenarios/inertia-2d.toml")),
        "inertia-3d" => Some(include_str!("../../../scenarios/inertia-3d.toml")),
        _ => None,
    }
}
