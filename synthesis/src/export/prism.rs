//! PRISM explicit-model export of an [`Mdp`]: `model.tra`, `model.sta`,
//! `model.lab`, `model.trew` (and a `model.props` with example queries), such
//! that `prism -importmodel OUTDIR/model.all -mdp` loads the abstraction.
//!
//! Numbering, labels and reward as in [`super`]. State variables (`.sta`): `dp` (decision
//! point; the terminals get `dp = D`, the number of decision points), `r` (index
//! of the state's region within its decision point) and `t` (0 = decision state,
//! 1 = coll, 2 = tar, 3 = free) — lexicographically increasing with the index.
//! The energy reward is a transition reward named `energy`: the choice's cost
//! on each of its transitions, so its expectation is the choice's cost.
//!
//! `model.props` holds the queries of [`super::queries`] ([`properties`]).
//!
//! Storm reads these files only after edits (its explicit parser wants a
//! model-type header instead of the counts line, no action column, no
//! comment line in the reward file and a `#DECLARATION … #END` labelling):
//! for Storm use [`super::jani`] or [`super::drn`].
//!
//! Formats: PRISM manual, appendix "Explicit Model Files" (MDP `.tra` lines
//! `i k j p [action]`; `.lab` header `0="init" 1="deadlock" …`; a reward file's
//! optional `# Reward structure "name"` comment names it).

use super::target_index;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::ParetoFront;
use std::fmt::Write as _;

/// The text of each exported file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PrismFiles {
    pub tra: String,
    pub sta: String,
    pub lab: String,
    pub trew: String,
    /// Example properties (multi-objective queries) for the labels and reward.
    pub props: String,
}

impl PrismFiles {
    /// `(file name, contents)` for every file, names as `model.<ext>`.
    pub fn files(&self) -> [(&'static str, &str); 5] {
        [
            ("model.tra", &self.tra),
            ("model.sta", &self.sta),
            ("model.lab", &self.lab),
            ("model.trew", &self.trew),
            ("model.props", &self.props),
        ]
    }
}

/// Export `mdp`, with the energy reward from cost model `cost` and the
/// properties `props` (e.g. from [`properties`]).
pub fn export(mdp: &Mdp, cost: CostModel, props: String) -> PrismFiles {
    let n = mdp.states.len();
    let choices: usize = mdp.states.iter().map(|s| s.choices.len()).sum::<usize>() + 3;
    let transitions = mdp.num_transitions() + 3;
    let dps = mdp.num_decision_points();

    // Writing into a String cannot fail; the results are ignored deliberately.
    let mut tra = String::with_capacity(64 * transitions);
    let _ = writeln!(tra, "{} {choices} {transitions}", n + 3);
    let mut rewards = Vec::new();
    for (i, s) in mdp.states.iter().enumerate() {
        for (k, c) in s.choices.iter().enumerate() {
            let r = c.cost(cost);
            for t in &c.transitions {
                let j = target_index(mdp, t.next);
                let _ = writeln!(tra, "{i} {k} {j} {} d{}", t.probability, c.action);
                if r > 0.0 {
                    rewards.push((i, k, j, r));
                }
            }
        }
    }
    for t in n..n + 3 {
        let _ = writeln!(tra, "{t} 0 {t} 1 done");
    }

    let mut trew = String::with_capacity(48 * rewards.len() + 64);
    let _ = writeln!(trew, "# Reward structure \"energy\"");
    let _ = writeln!(trew, "{} {choices} {}", n + 3, rewards.len());
    for (i, k, j, r) in rewards {
        let _ = writeln!(trew, "{i} {k} {j} {r}");
    }

    let mut sta = String::with_capacity(16 * (n + 4));
    let _ = writeln!(sta, "(dp,r,t)");
    let mut prev_dp = u32::MAX;
    let mut r = 0usize;
    for (i, s) in mdp.states.iter().enumerate() {
        if s.decision_point == prev_dp {
            r += 1;
        } else {
            prev_dp = s.decision_point;
            r = 0;
        }
        let _ = writeln!(sta, "{i}:({},{r},0)", s.decision_point);
    }
    for (k, t) in (n..n + 3).enumerate() {
        let _ = writeln!(sta, "{t}:({dps},0,{})", k + 1);
    }

    let mut lab = String::new();
    let _ = writeln!(
        lab,
        "0=\"init\" 1=\"deadlock\" 2=\"coll\" 3=\"tar\" 4=\"free\""
    );
    let _ = writeln!(lab, "{}: 0", mdp.initial);
    for (k, t) in (n..n + 3).enumerate() {
        let _ = writeln!(lab, "{t}: {}", k + 2);
    }

    PrismFiles {
        tra,
        sta,
        lab,
        trew,
        props,
    }
}

/// `model.props` for `mdp` from its front ([`super::queries`]).
pub fn properties(mdp: &Mdp, front: &ParetoFront, cost: CostModel) -> String {
    super::properties_file(mdp, &super::queries(mdp, front, cost))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mdp::tests::toy;

    #[test]
    fn toy_export_is_consistent() {
        let m = toy();
        let f = export(&m, CostModel::Counted, String::new());
        let mut lines = f.tra.lines();
        let header: Vec<usize> = lines
            .next()
            .expect("header")
            .split(' ')
            .map(|x| x.parse().expect("number"))
            .collect();
        assert_eq!(header, vec![6, 9, 15]);
        let body: Vec<&str> = lines.collect();
        assert_eq!(body.len(), 15);
        // Every choice sums to 1.
        let mut sums = std::collections::BTreeMap::<(usize, usize), f64>::new();
        for l in &body {
            let p: Vec<&str> = l.split(' ').collect();
            assert_eq!(p.len(), 5);
            let key = (p[0].parse().expect("i"), p[1].parse().expect("k"));
            *sums.entry(key).or_default() += p[3].parse::<f64>().expect("p");
        }
        assert_eq!(sums.len(), 9);
        assert!(sums.values().all(|s| (s - 1.0).abs() < 1e-12));
        assert!(body.contains(&"0 1 3 0.3 d1"));
        assert!(body.contains(&"5 0 5 1 done"));
        assert!(
            f.sta
                .starts_with("(dp,r,t)\n0:(0,0,0)\n1:(1,0,0)\n2:(1,1,0)\n3:(2,0,1)\n")
        );
        assert_eq!(
            f.lab,
            "0=\"init\" 1=\"deadlock\" 2=\"coll\" 3=\"tar\" 4=\"free\"\n0: 0\n3: 2\n4: 3\n5: 4\n"
        );
        let rew: Vec<&str> = f.trew.lines().collect();
        assert_eq!(rew[0], "# Reward structure \"energy\"");
        assert_eq!(rew[1], "6 9 12");
        assert!(rew.contains(&"0 0 1 10"));
    }

    #[test]
    fn properties_take_thresholds_from_the_front() {
        let m = toy();
        let front = crate::pareto::compute_front(&m, CostModel::Counted).expect("front");
        let props = properties(&m, &front, CostModel::Counted);
        // The toy's P_tar ranges over [0.35, 0.855]: three quarters up is 0.728.
        assert!(props.contains("P>=0.728 [ F \"tar\" ])"), "{props}");
        // The highest P_tar is 0.855, so 0.856 is the infeasible example.
        assert!(props.contains("INFEASIBLE"), "{props}");
        assert!(props.contains("P>=0.856 [ F \"tar\" ])"), "{props}");
        assert!(props.contains("// etp: 0.855000000000"), "{props}");
        // Every feasible multi query is followed by etp's exact energy.
        let lines: Vec<&str> = props.lines().collect();
        for (k, l) in lines.iter().enumerate() {
            if l.starts_with("multi(") && l.contains("P>=0.728") {
                let answer = lines[k + 1].strip_prefix("// etp: ").expect("an answer");
                assert!(answer.parse::<f64>().is_ok(), "{answer}");
            }
        }
        // Comments name what the query computes.
        assert!(props.contains("// Lowest probability of colliding\nPmin=?"));
        assert!(props.contains("// Highest probability of reaching the target\nPmax=?"));
    }
}
