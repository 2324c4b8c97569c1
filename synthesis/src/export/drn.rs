//! Storm's explicit DRN format of an [`Mdp`] (`model.drn`), loadable with
//! `storm --explicit-drn model.drn --prop model.props` or stormpy's
//! `build_model_from_drn`. Numbering, labels and reward as in [`super`]: each
//! state line carries its labels, each choice its action name `d<k>` and its
//! energy as the action reward of the reward model `energy`.
//!
//! Format: Storm's `DirectEncodingParser` (a header of `@type`,
//! `@parameters`, `@reward_models`, `@nr_states`, `@nr_choices`, then
//! `@model` with `state i [labels]`, `\taction name [rewards]` and
//! `\t\tj : p` lines).

use super::{TERMINAL_LABELS, number, target_index};
use crate::mdp::{CostModel, Mdp};
use std::fmt::Write as _;

/// The DRN text of `mdp`, with the energy reward from cost model `cost`.
pub fn export(mdp: &Mdp, cost: CostModel) -> String {
    let n = mdp.states.len();
    let choices: usize = mdp.states.iter().map(|s| s.choices.len()).sum::<usize>() + 3;
    let mut o = String::with_capacity(32 * (mdp.num_transitions() + choices) + 512);
    // Writing into a String cannot fail; the results are ignored deliberately.
    let _ = writeln!(
        o,
        "// etp MDP of scenario \"{}\" (scenario hash {:.12}…): states 0 to {} choose a\n\
         // threshold (action d<k> is deltas[k]), {n} = coll, {} = tar, {} = free;\n\
         // the reward \"energy\" is each choice's expected energy.",
        mdp.scenario_name,
        mdp.scenario_hash,
        n.saturating_sub(1),
        n + 1,
        n + 2
    );
    let _ = writeln!(o, "@type: MDP\n@parameters\n\n@reward_models\nenergy");
    let _ = writeln!(o, "@nr_states\n{}\n@nr_choices\n{choices}\n@model", n + 3);
    for (i, s) in mdp.states.iter().enumerate() {
        if i == mdp.initial as usize {
            let _ = writeln!(o, "state {i} init");
        } else {
            let _ = writeln!(o, "state {i}");
        }
        for c in &s.choices {
            let _ = writeln!(o, "\taction d{} [{}]", c.action, number(c.cost(cost)));
            for t in &c.transitions {
                let j = target_index(mdp, t.next);
                let _ = writeln!(o, "\t\t{j} : {}", number(t.probability));
            }
        }
    }
    for (k, label) in TERMINAL_LABELS.iter().enumerate() {
        let t = n + k;
        let _ = writeln!(o, "state {t} {label}\n\taction done [0]\n\t\t{t} : 1");
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mdp::tests::toy;

    #[test]
    fn toy_drn_declares_what_it_holds() {
        let m = toy();
        let d = export(&m, CostModel::Counted);
        let body: Vec<&str> = d.lines().filter(|l| !l.starts_with("//")).collect();
        assert_eq!(
            &body[..10],
            &[
                "@type: MDP",
                "@parameters",
                "",
                "@reward_models",
                "energy",
                "@nr_states",
                "6",
                "@nr_choices",
                "9",
                "@model"
            ]
        );
        assert_eq!(body.iter().filter(|l| l.starts_with("state ")).count(), 6);
        assert_eq!(
            body.iter().filter(|l| l.starts_with("\taction ")).count(),
            9
        );
        assert_eq!(body.iter().filter(|l| l.starts_with("\t\t")).count(), 15);
        assert!(d.contains("state 0 init\n\taction d0 [10]\n"), "{d}");
        assert!(d.contains("\t\t3 : 0.3\n"), "{d}");
        assert!(
            d.ends_with("state 5 free\n\taction done [0]\n\t\t5 : 1\n"),
            "{d}"
        );
    }
}
