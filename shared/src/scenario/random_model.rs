//! The agent's model and controller, its sensors and its thresholds as
//! scenario TOML for `random_scenario_toml` (the draws in the order the
//! scenario's seed fixes).

use super::{AgentKind, diag, fmt_mat, fmt_vec, r3, random_r};
use crate::gaussian::delta_for_rate;
use rand::{Rng, RngExt};
use std::fmt::Write;

/// The `[model]` keys and the `[controller]` table of the agent starting
/// at `start`: a double integrator under an LQR or a PD gain, or a single
/// integrator.
pub(super) fn write_model_and_controller<R: Rng + ?Sized>(
    o: &mut String,
    rng: &mut R,
    kind: AgentKind,
    start: &[f64],
) {
    let (n, d) = (kind.dim(), kind.workspace_dim());
    let tau = 0.1;
    let eye = |k: usize| diag(&vec![1.0; k]);
    let mut lqr = None;
    let mut gain = None;
    let (u_max, eps_x, k_max);
    if kind.double() {
        let mut f = eye(n);
        let mut gm = vec![vec![0.0; d]; n];
        let mut c = vec![vec![0.0; n]; d];
        for k in 0..d {
            f[k][d + k] = tau;
            gm[k][k] = tau * tau / 2.0;
            gm[d + k][k] = tau;
            c[k][k] = 1.0;
        }
        let qv = (rng.random_range(0.6e-3..1.2e-3_f64) * 1e6).round() / 1e6;
        let q: Vec<f64> = (0..n).map(|k| if k < d { 1e-6 } else { qv }).collect();
        let p0: Vec<f64> = (0..n).map(|k| if k < d { 0.0009 } else { 0.001 }).collect();
        let mut x0 = start.to_vec();
        x0.extend(std::iter::repeat_n(0.0, d));
        let _ = writeln!(
            o,
            "# x = (position, velocity), tau = {tau}: F = [[I, tau I], [0, I]], G = [[tau^2/2 I], [tau I]]"
        );
        let _ = writeln!(
            o,
            "F = {}\nG = {}\nC = {}",
            fmt_mat(&f),
            fmt_mat(&gm),
            fmt_mat(&c)
        );
        let _ = writeln!(
            o,
            "Q = {}\nx0 = {}\nP0 = {}",
            fmt_mat(&diag(&q)),
            fmt_vec(&x0),
            fmt_mat(&diag(&p0))
        );
        if rng.random_bool(0.7) {
            let wv = r3(rng.random_range(0.2..0.5));
            let wu = r3(rng.random_range(0.3..1.0));
            let state: Vec<f64> = (0..n).map(|k| if k < d { 1.0 } else { wv }).collect();
            lqr = Some((diag(&state), diag(&vec![wu; d])));
        } else {
            // a PD gain: natural frequency ω, damping ζ (stable for τ ω ≪ 1)
            let omega = rng.random_range(1.0..1.4);
            let zeta = rng.random_range(0.7..0.9);
            let (kp, kd) = (r3(omega * omega), r3(2.0 * zeta * omega));
            let mut k = vec![vec![0.0; n]; d];
            for (a, row) in k.iter_mut().enumerate() {
                row[a] = kp;
                row[d + a] = kd;
            }
            gain = Some(k);
        }
        (u_max, eps_x, k_max) = (1.0, 0.1, 120);
    } else {
        let q = r3(rng.random_range(0.06..0.075));
        let q2 = (q * q * 1e6).round() / 1e6;
        let _ = writeln!(o, "F = {}\nG = {}", fmt_mat(&eye(n)), fmt_mat(&eye(n)));
        let _ = writeln!(
            o,
            "Q = {}\nx0 = {}\nP0 = {}",
            fmt_mat(&diag(&vec![q2; n])),
            fmt_vec(start),
            fmt_mat(&diag(&vec![0.0009; n]))
        );
        (u_max, eps_x, k_max) = (0.05, 0.05, 200);
    }
    let _ = writeln!(
        o,
        "\n[controller]\nu_max = {u_max:?}\neps_x = {eps_x:?}\nk_max = {k_max}"
    );
    if let Some(k) = &gain {
        let _ = writeln!(o, "K = {}", fmt_mat(k));
    }
    if let Some((state, input)) = &lqr {
        let _ = writeln!(
            o,
            "\n[controller.lqr]\nstate = {}\ninput = {}",
            fmt_mat(state),
            fmt_mat(input)
        );
    }
}

/// One `[[sensor]]` per sensor of `serving`: placed near the middle of the
/// legs it serves, observing the position with a rotated anisotropic R.
pub(super) fn write_sensors<R: Rng + ?Sized>(
    o: &mut String,
    rng: &mut R,
    kind: AgentKind,
    points: &[Vec<f64>],
    serving: &[usize],
) {
    let (n, d) = (kind.dim(), kind.workspace_dim());
    let sensors = serving.last().map_or(0, |&s| s + 1);
    for s in 0..sensors {
        let served: Vec<usize> = (0..serving.len()).filter(|&i| serving[i] == s).collect();
        let mut centre = vec![0.0; d];
        for &i in &served {
            for (k, c) in centre.iter_mut().enumerate() {
                *c += 0.5 * (points[i][k] + points[i + 1][k]) / served.len() as f64;
            }
        }
        let position: Vec<f64> = centre
            .iter()
            .map(|c| r3(c + rng.random_range(-0.6..0.6)))
            .collect();
        let mut h = vec![vec![0.0; n]; d];
        for (k, row) in h.iter_mut().enumerate() {
            row[k] = 1.0;
        }
        let r = random_r(rng, d);
        let _ = writeln!(
            o,
            "\n[[sensor]]\nname = \"s{s}\"\nposition = {}\nH = {}\nR = {}\ncost = 1.0",
            fmt_vec(&position),
            fmt_mat(&h),
            fmt_mat(&r)
        );
    }
}

/// The `[triggering]` table: thresholds for expected trigger rates from 1
/// (δ = 0, the full KF) down to 0.05 (d = 3 adds 0.65).
pub(super) fn write_triggering(o: &mut String, d: usize) {
    let rates: &[f64] = if d == 3 {
        &[1.0, 0.65, 0.5, 0.25, 0.1, 0.05]
    } else {
        &[1.0, 0.5, 0.25, 0.1, 0.05]
    };
    let deltas: Vec<f64> = rates
        .iter()
        .map(|&r| {
            if r >= 1.0 {
                0.0
            } else {
                (delta_for_rate(r, d) * 1e4).round() / 1e4
            }
        })
        .collect();
    let rate_list: Vec<String> = rates.iter().map(|r| format!("{r}")).collect();
    let _ = writeln!(
        o,
        "\n[triggering]\n# expected trigger rates 1 - (2 Phi(delta) - 1)^{d}: {}\ndeltas = {}",
        rate_list.join(", "),
        fmt_vec(&deltas)
    );
}
