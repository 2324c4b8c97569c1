//! A family of random but valid scenarios (issue 25): what claims about the
//! abstraction are measured on, so that nothing can be tuned to the shipped
//! scenarios.
//!
//! [`random_scenario_toml`] draws one scenario from an RNG the caller passes in
//! and returns its TOML text (same RNG state, same text, on every platform: only
//! IEEE-exact arithmetic and `libm`); [`random_scenario`] derives the RNG from a
//! seed and also parses the text with [`Scenario::from_toml`], so a generated
//! scenario is exactly what a user loading the file gets.
//!
//! What is drawn (the built-in scenarios' conventions, randomised):
//! * the agent ([`AgentKind`]): a single integrator in the plane or in space
//!   (n = 2, 3; F = G = H = I, like `winding-2d`) or a double integrator
//!   (n = 4, 6; time step τ = 0.1, position-only sensors, like `inertia-2d`),
//!   the latter tracked by an LQR gain (random weights) or an explicit PD gain;
//! * a route of 5–8 axis-aligned legs turning at most corners (no reversal,
//!   non-adjacent legs kept apart);
//! * obstacles the route must thread: gates across legs (two bars in the
//!   plane, a square frame in space), walls beyond corners where the carried
//!   velocity overshoots, a dock beyond the target; every obstacle keeps every
//!   leg clear by a margin (a gate its own leg by its half-width), checked on
//!   the rounded numbers that are written;
//! * 3–7 sensors serving contiguous runs of legs, each with a random
//!   anisotropic R (random rotation, σ ratio up to 3);
//! * Δ with expected rates 1, 0.5, 0.25, 0.1, 0.05 (and 0.65 for m = 3), as the
//!   built-ins.

use super::{Scenario, ScenarioError};
use crate::rng::stream_rng;
use rand::{Rng, RngExt};
use std::fmt::Write;

/// The RNG stream of [`random_scenario`] (its own, so a scenario seed shares
/// no numbers with a simulation under the same seed).
const SCENARIO_STREAM: u64 = 0x5CE7_A710;

/// Which agent a random scenario has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AgentKind {
    /// n = d = 2, F = G = H = I, K = I.
    Single2,
    /// n = d = 3, F = G = H = I, K = I.
    Single3,
    /// n = 4, d = 2: planar double integrator.
    Double2,
    /// n = 6, d = 3: spatial double integrator.
    Double3,
}

impl AgentKind {
    /// The kind for a state dimension n ∈ {2, 3, 4, 6}.
    pub fn from_dim(n: usize) -> Result<Self, ScenarioError> {
        match n {
            2 => Ok(Self::Single2),
            3 => Ok(Self::Single3),
            4 => Ok(Self::Double2),
            6 => Ok(Self::Double3),
            _ => Err(ScenarioError::invalid(
                "dim",
                format!(
                    "a random scenario has n = 2, 3 (single integrator), 4 or 6 (double integrator), not {n}"
                ),
            )),
        }
    }

    /// State dimension n.
    pub fn dim(self) -> usize {
        match self {
            Self::Single2 => 2,
            Self::Single3 => 3,
            Self::Double2 => 4,
            Self::Double3 => 6,
        }
    }

    /// Workspace dimension d.
    pub fn workspace_dim(self) -> usize {
        match self {
            Self::Single2 | Self::Double2 => 2,
            Self::Single3 | Self::Double3 => 3,
        }
    }

    fn double(self) -> bool {
        matches!(self, Self::Double2 | Self::Double3)
    }
}

/// Scale of the geometry: the built-in of the same agent kind sets it.
#[derive(Debug, Clone, Copy)]
struct Geometry {
    /// Leg lengths are drawn from this range.
    leg: (f64, f64),
    /// Distance kept between non-adjacent legs.
    separation: f64,
    /// Every obstacle keeps every leg (but a gate's own) at least this far.
    margin: f64,
    /// Gate half-widths.
    gate: (f64, f64),
    /// Distance of a wall beyond its corner.
    overshoot: (f64, f64),
    /// Half-width of the target box.
    target: f64,
    /// Thickness of walls and gate bars.
    wall: f64,
}

impl Geometry {
    fn of(kind: AgentKind) -> Self {
        if kind.double() {
            // inertia-2d/3d: legs 2.5–3, gates 0.35–0.4, walls 0.6–0.7 beyond corners
            Self {
                leg: (2.2, 3.4),
                separation: 1.6,
                margin: 0.45,
                gate: (0.3, 0.45),
                overshoot: (0.5, 0.8),
                target: 0.15,
                wall: 0.2,
            }
        } else {
            // winding-2d: legs 2–3.5, gates ≈ 0.48, walls ≈ 0.36 beyond corners
            Self {
                leg: (2.0, 3.4),
                separation: 1.5,
                margin: 0.3,
                gate: (0.38, 0.55),
                overshoot: (0.32, 0.5),
                target: 0.12,
                wall: 0.3,
            }
        }
    }
}

/// An axis-aligned box being placed.
#[derive(Debug, Clone)]
struct Block {
    name: String,
    min: Vec<f64>,
    max: Vec<f64>,
    /// A gate bar: its own leg only needs the gate's half-width.
    gate_of: Option<(usize, f64)>,
}

/// Round to 1e-3 (what is written, and what the clearance is checked on).
fn r3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

fn point_box_distance(p: &[f64], min: &[f64], max: &[f64]) -> f64 {
    p.iter()
        .zip(min.iter().zip(max))
        .map(|(x, (lo, hi))| (lo - x).max(x - hi).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn lerp(a: &[f64], b: &[f64], t: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect()
}

/// Distance from segment ab to a box: the distance to a convex set is convex
/// along the segment, so a ternary search finds its minimum.
fn segment_box_distance(a: &[f64], b: &[f64], min: &[f64], max: &[f64]) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..100 {
        let m1 = lo + (hi - lo) / 3.0;
        let m2 = hi - (hi - lo) / 3.0;
        if point_box_distance(&lerp(a, b, m1), min, max)
            <= point_box_distance(&lerp(a, b, m2), min, max)
        {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    point_box_distance(&lerp(a, b, 0.5 * (lo + hi)), min, max)
}

/// Distance between two segments (sampled along the first, exact to the
/// second's points: enough to keep legs apart).
fn segment_distance(a: &[f64], b: &[f64], c: &[f64], d: &[f64]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..=200 {
        let p = lerp(a, b, f64::from(i) / 200.0);
        // distance from p to segment cd
        let cd: Vec<f64> = c.iter().zip(d).map(|(x, y)| y - x).collect();
        let cp: Vec<f64> = c.iter().zip(&p).map(|(x, y)| y - x).collect();
        let len2: f64 = cd.iter().map(|x| x * x).sum();
        let t = if len2 > 0.0 {
            (cd.iter().zip(&cp).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = lerp(c, d, t);
        let dist: f64 = p
            .iter()
            .zip(&q)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt();
        best = best.min(dist);
    }
    best
}

/// One leg of the route under construction: the axis it runs along and its sign.
#[derive(Debug, Clone, Copy)]
struct Step {
    axis: usize,
    sign: f64,
}

/// Draw a route: `points[0]` is the start, `points[i + 1]` the end of leg i.
fn draw_route<R: Rng + ?Sized>(rng: &mut R, d: usize, g: &Geometry) -> (Vec<Vec<f64>>, Vec<Step>) {
    let start: Vec<f64> = [0.5, 1.0, 1.0][..d].to_vec();
    'route: loop {
        let legs = rng.random_range(5..=8usize);
        let mut points = vec![start.clone()];
        let mut steps: Vec<Step> = Vec::new();
        for i in 0..legs {
            let mut placed = false;
            for _attempt in 0..40 {
                let step = match steps.last() {
                    // mostly turns; a straight continuation now and then
                    Some(prev) if rng.random_bool(0.15) => *prev,
                    Some(prev) => {
                        let others: Vec<usize> = (0..d).filter(|&a| a != prev.axis).collect();
                        Step {
                            axis: others[rng.random_range(0..others.len())],
                            sign: if rng.random_bool(0.5) { 1.0 } else { -1.0 },
                        }
                    }
                    None => Step { axis: 0, sign: 1.0 },
                };
                let len = r3(rng.random_range(g.leg.0..g.leg.1));
                let from = &points[i];
                let mut to = from.clone();
                to[step.axis] = r3(to[step.axis] + step.sign * len);
                // keep apart from every non-adjacent leg so obstacles fit between
                let clear = (0..i.saturating_sub(1)).all(|j| {
                    segment_distance(from, &to, &points[j], &points[j + 1]) >= g.separation
                });
                if clear {
                    points.push(to);
                    steps.push(step);
                    placed = true;
                    break;
                }
            }
            if !placed {
                continue 'route;
            }
        }
        return (points, steps);
    }
}

/// Whether a box keeps every leg clear (and the target box and start free).
fn keeps_clear(b: &Block, points: &[Vec<f64>], g: &Geometry, target: (&[f64], &[f64])) -> bool {
    for i in 0..points.len() - 1 {
        let need = match b.gate_of {
            Some((leg, half)) if leg == i => half,
            _ => g.margin,
        };
        if segment_box_distance(&points[i], &points[i + 1], &b.min, &b.max) < need - 1e-9 {
            return false;
        }
    }
    // the target box itself must stay free
    let overlap = (0..b.min.len()).all(|k| b.min[k] <= target.1[k] && b.max[k] >= target.0[k]);
    !overlap
}

/// A slab perpendicular to `axis` at `at .. at + sign·thickness`, spanning
/// `span[k]` on the other axes.
fn slab(
    name: String,
    axis: usize,
    at: f64,
    sign: f64,
    thickness: f64,
    span: &[(f64, f64)],
) -> Block {
    let mut min: Vec<f64> = span.iter().map(|s| r3(s.0)).collect();
    let mut max: Vec<f64> = span.iter().map(|s| r3(s.1)).collect();
    let (a, b) = (at, at + sign * thickness);
    min[axis] = r3(a.min(b));
    max[axis] = r3(a.max(b));
    Block {
        name,
        min,
        max,
        gate_of: None,
    }
}

/// Gate across leg `leg` at fraction `t`: the leg passes through a square
/// hole of half-width `half` (two bars in the plane, four in space).
fn gate(
    name: &str,
    leg: usize,
    points: &[Vec<f64>],
    step: Step,
    t: f64,
    half: f64,
    g: &Geometry,
) -> Vec<Block> {
    let (from, to) = (&points[leg], &points[leg + 1]);
    let d = from.len();
    let centre = lerp(from, to, t);
    let at = centre[step.axis] - 0.5 * g.wall.min(0.1);
    let thick = g.wall.min(0.1);
    let arm = 1.1;
    let others: Vec<usize> = (0..d).filter(|&a| a != step.axis).collect();
    let mut blocks = Vec::new();
    // bars on the first cross axis span the whole frame on the second (if any)
    for (k, &cross) in others.iter().enumerate() {
        for (side, sgn) in [("-", -1.0), ("+", 1.0)] {
            let mut span: Vec<(f64, f64)> = centre.iter().map(|&c| (c, c)).collect();
            let (lo, hi) = if sgn < 0.0 {
                (centre[cross] - half - arm, centre[cross] - half)
            } else {
                (centre[cross] + half, centre[cross] + half + arm)
            };
            span[cross] = (lo, hi);
            for (j, &other) in others.iter().enumerate() {
                if j == k {
                    continue;
                }
                // the first cross axis' bars cover the full height; the
                // second's only the hole's band, so the four bars tile a frame
                span[other] = if k == 0 {
                    (centre[other] - half - arm, centre[other] + half + arm)
                } else {
                    (centre[other] - half, centre[other] + half)
                };
            }
            let axis_name = ["x", "y", "z"][cross];
            let mut b = slab(
                format!("{name}-{axis_name}{side}"),
                step.axis,
                at,
                1.0,
                thick,
                &span,
            );
            b.gate_of = Some((leg, half));
            blocks.push(b);
        }
    }
    blocks
}

/// Wall beyond the corner at the end of leg `leg` (incoming `step`), reaching
/// back along the incoming leg and forward along the outgoing one.
fn corner_wall(
    name: String,
    corner: &[f64],
    step: Step,
    next: Option<(Step, f64)>,
    offset: f64,
    g: &Geometry,
) -> Block {
    let mut span: Vec<(f64, f64)> = corner.iter().map(|&c| (c - 1.0, c + 1.0)).collect();
    if let Some((out, len)) = next {
        let reach = 0.6 * len;
        span[out.axis] = if out.sign > 0.0 {
            (corner[out.axis] - 1.0, corner[out.axis] + reach)
        } else {
            (corner[out.axis] - reach, corner[out.axis] + 1.0)
        };
    }
    slab(
        name,
        step.axis,
        corner[step.axis] + step.sign * offset,
        step.sign,
        g.wall,
        &span,
    )
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", parts.join(", "))
}

fn fmt_mat(m: &[Vec<f64>]) -> String {
    let rows: Vec<String> = m.iter().map(|r| fmt_vec(r)).collect();
    format!("[{}]", rows.join(", "))
}

fn diag(v: &[f64]) -> Vec<Vec<f64>> {
    (0..v.len())
        .map(|i| {
            (0..v.len())
                .map(|j| if i == j { v[i] } else { 0.0 })
                .collect()
        })
        .collect()
}

/// Rotation matrix of angle `a` in the plane of axes (i, j), in R^d.
fn givens(d: usize, i: usize, j: usize, a: f64) -> Vec<Vec<f64>> {
    let mut m = diag(&vec![1.0; d]);
    let (s, c) = (libm::sin(a), libm::cos(a));
    m[i][i] = c;
    m[j][j] = c;
    m[i][j] = -s;
    m[j][i] = s;
    m
}

fn mat_mul(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = a.len();
    let m = b[0].len();
    (0..n)
        .map(|i| {
            (0..m)
                .map(|j| (0..b.len()).map(|k| a[i][k] * b[k][j]).sum())
                .collect()
        })
        .collect()
}

/// A random anisotropic measurement covariance `V diag(σ²) Vᵀ`: σ of the
/// finest axis in [0.02, 0.035], the others up to 3 times that, V a random
/// rotation (rounded to 1e-12 and symmetric by construction).
fn random_r<R: Rng + ?Sized>(rng: &mut R, d: usize) -> Vec<Vec<f64>> {
    let sigma0 = rng.random_range(0.02..0.035);
    let sig: Vec<f64> = (0..d)
        .map(|k| {
            if k == 0 {
                sigma0
            } else {
                sigma0 * rng.random_range(1.0..3.0)
            }
        })
        .collect();
    let mut v = diag(&vec![1.0; d]);
    for i in 0..d {
        for j in i + 1..d {
            let a = rng.random_range(0.0..std::f64::consts::PI);
            v = mat_mul(&v, &givens(d, i, j, a));
        }
    }
    let var: Vec<f64> = sig.iter().map(|s| s * s).collect();
    let vd: Vec<Vec<f64>> = v
        .iter()
        .map(|row| row.iter().zip(&var).map(|(x, s)| x * s).collect())
        .collect();
    let vt: Vec<Vec<f64>> = (0..d).map(|i| (0..d).map(|j| v[j][i]).collect()).collect();
    let full = mat_mul(&vd, &vt);
    // the upper triangle, mirrored: symmetric to the last bit
    (0..d)
        .map(|i| {
            (0..d)
                .map(|j| (full[i.min(j)][i.max(j)] * 1e12).round() / 1e12)
                .collect()
        })
        .collect()
}

/// Draw one scenario's TOML text from `rng` (named `name`).
pub fn random_scenario_toml<R: Rng + ?Sized>(kind: AgentKind, name: &str, rng: &mut R) -> String {
    let (n, d) = (kind.dim(), kind.workspace_dim());
    let g = Geometry::of(kind);
    let (points, steps) = draw_route(rng, d, &g);
    let legs = steps.len();
    let last = &points[legs];
    let target_min: Vec<f64> = last.iter().map(|c| r3(c - g.target)).collect();
    let target_max: Vec<f64> = last.iter().map(|c| r3(c + g.target)).collect();
    let obstacles = draw_obstacles(rng, &points, &steps, &g, (&target_min, &target_max));
    let serving = draw_serving(rng, legs);
    let sensors = serving.last().map_or(0, |&s| s + 1);

    // the agent
    let mut o = String::new();
    let agent = if kind.double() {
        format!("{}-D double integrator (n = {n})", d)
    } else {
        format!("{}-D single integrator (n = {n})", d)
    };
    let _ = writeln!(o, "name = \"{name}\"");
    let _ = writeln!(
        o,
        "description = \"random scenario (etp scenario random): {agent}, {legs} legs, {sensors} sensors with rotated anisotropic R, {} gate(s), {} wall(s) beyond corners\"",
        obstacles.gates, obstacles.walls
    );
    let _ = writeln!(o, "dim = {n}\n\n[model]");
    write_model_and_controller(&mut o, rng, kind, &points[0]);
    write_sensors(&mut o, rng, kind, &points, &serving);
    for i in 0..legs {
        let _ = writeln!(
            o,
            "\n[[leg]]\nto = {}\nsensor = \"s{}\"",
            fmt_vec(&points[i + 1]),
            serving[i]
        );
    }
    let _ = writeln!(
        o,
        "\n[target]\nmin = {}\nmax = {}",
        fmt_vec(&target_min),
        fmt_vec(&target_max)
    );
    for b in &obstacles.blocks {
        let _ = writeln!(
            o,
            "\n[[obstacle]]\nname = \"{}\"\nmin = {}\nmax = {}",
            b.name,
            fmt_vec(&b.min),
            fmt_vec(&b.max)
        );
    }
    write_triggering(&mut o, d);
    o
}

/// The obstacles of a route, and how many gates and walls they are.
struct Obstacles {
    blocks: Vec<Block>,
    gates: usize,
    walls: usize,
}

/// Gates on 1–3 long legs, walls beyond most corners, a dock; each kept
/// only if it keeps the route and the target clear.
fn draw_obstacles<R: Rng + ?Sized>(
    rng: &mut R,
    points: &[Vec<f64>],
    steps: &[Step],
    g: &Geometry,
    target: (&[f64], &[f64]),
) -> Obstacles {
    let legs = steps.len();
    let mut blocks: Vec<Block> = Vec::new();
    let accept = |candidate: Vec<Block>, blocks: &mut Vec<Block>| {
        if candidate.iter().all(|b| keeps_clear(b, points, g, target)) {
            blocks.extend(candidate);
            true
        } else {
            false
        }
    };
    let gates = rng.random_range(1..=3usize);
    let mut gate_count = 0;
    for _ in 0..3 * gates {
        if gate_count == gates {
            break;
        }
        let leg = rng.random_range(1..legs);
        let t = rng.random_range(0.35..0.65);
        let half = r3(rng.random_range(g.gate.0..g.gate.1));
        let cand = gate(
            &format!("gate{}", gate_count + 1),
            leg,
            points,
            steps[leg],
            t,
            half,
            g,
        );
        if accept(cand, &mut blocks) {
            gate_count += 1;
        }
    }
    let mut walls = 0;
    for leg in 0..legs {
        let next = steps.get(leg + 1).map(|s| {
            let len = (points[leg + 2][s.axis] - points[leg + 1][s.axis]).abs();
            (*s, len)
        });
        let turns = next.is_none_or(|(s, _)| s.axis != steps[leg].axis);
        let offset = rng.random_range(g.overshoot.0..g.overshoot.1);
        let wanted = rng.random_bool(0.75);
        if !turns || !(wanted || next.is_none()) {
            continue;
        }
        let label = if next.is_none() {
            "dock".to_string()
        } else {
            walls += 1;
            format!("wall{walls}")
        };
        let w = corner_wall(label, &points[leg + 1], steps[leg], next, offset, g);
        accept(vec![w], &mut blocks);
    }
    Obstacles {
        blocks,
        gates: gate_count,
        walls,
    }
}

/// The sensor serving each leg: 3–7 sensors, each serving a contiguous run
/// of legs, numbered in route order.
fn draw_serving<R: Rng + ?Sized>(rng: &mut R, legs: usize) -> Vec<usize> {
    let sensors = rng.random_range(3..=7usize.min(legs));
    let mut cuts: Vec<usize> = Vec::new();
    while cuts.len() < sensors - 1 {
        let c = rng.random_range(1..legs);
        if !cuts.contains(&c) {
            cuts.push(c);
        }
    }
    cuts.sort_unstable();
    (0..legs)
        .map(|i| cuts.iter().filter(|&&c| c <= i).count())
        .collect()
}

/// The scenario of `seed` for agent kind `kind`: its TOML text (named
/// `random-n{n}-s{seed}`) and the parsed, validated scenario.
pub fn random_scenario(kind: AgentKind, seed: u64) -> Result<(String, Scenario), ScenarioError> {
    let mut rng = stream_rng(seed, SCENARIO_STREAM, kind.dim() as u64);
    let name = format!("random-n{}-s{seed}", kind.dim());
    let text = random_scenario_toml(kind, &name, &mut rng);
    let scenario = Scenario::from_toml(&text)?;
    Ok((text, scenario))
}

#[cfg(test)]
#[path = "random_tests.rs"]
mod tests;

#[path = "random_model.rs"]
mod model;
use model::{write_model_and_controller, write_sensors, write_triggering};
