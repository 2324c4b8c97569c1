//! The JANI model of an [`Mdp`] (`model.jani`, the QComp interchange
//! format), with the queries of [`super::queries`] as its properties:
//! `storm --jani model.jani --janiproperty`, or stormpy's
//! `parse_jani_model` and `build_model`.
//!
//! One automaton with one location; the state is the global variable `s`
//! (numbering of [`super`]). Each choice is an edge with action `d<k>`,
//! guard `s = i` and one destination per transition. The labels `coll`,
//! `tar` and `free` are transient Boolean variables set by the location
//! (`s = S`, `S + 1`, `S + 2`); the energy reward is the transient real
//! variable `energy`, assigned the choice's cost on each of its destinations
//! (a transition reward whose expectation is the choice's cost). The
//! multi-objective queries use the `Multi` operator of the feature
//! `multi-objective-properties` (Storm's JANI extension; `Emin` with
//! `accumulate: ["steps"]` and no `reach` is the total reward `C`).
//!
//! Format: the JANI specification (jani-spec.org), model version 1.

use super::{Formula, Query, TERMINAL_LABELS, target_index};
use crate::mdp::{CostModel, Mdp};
use serde_json::{Value, json};

/// `s = k`.
fn state_is(k: usize) -> Value {
    json!({"op": "=", "left": "s", "right": k})
}

/// `P<opt>=? [ F label ]` as JANI (`true U label`).
fn reach(opt: &str, label: &str) -> Value {
    json!({"op": opt, "exp": {"op": "U", "left": true, "right": label}})
}

/// `R{"energy"}min=? [ C ]`: the expected total energy.
fn energy() -> Value {
    json!({"op": "Emin", "exp": "energy", "accumulate": ["steps"]})
}

/// `left <op> bound` with a probability operator on the left.
fn bounded(op: &str, left: Value, bound: f64) -> Value {
    json!({"op": op, "left": left, "right": bound})
}

/// The JANI expression of one query (before the filter on the initial state).
fn formula(f: &Formula) -> Value {
    match *f {
        Formula::LeastEnergy {
            min_target,
            max_collision,
        } => {
            let mut parts = vec![json!({"exp": energy(), "opt": "min"})];
            if let Some(p) = min_target {
                parts.push(json!({"exp": bounded("≥", reach("Pmax", "tar"), p)}));
            }
            if let Some(c) = max_collision {
                parts.push(json!({"exp": bounded("≤", reach("Pmin", "coll"), c)}));
            }
            json!({"op": "Multi", "type": "tradeoff", "properties": parts})
        }
        Formula::MaxTarget => reach("Pmax", "tar"),
        Formula::MinCollision => reach("Pmin", "coll"),
        Formula::ParetoTarget => json!({
            "op": "Multi",
            "type": "tradeoff",
            "properties": [
                {"exp": energy(), "opt": "min"},
                {"exp": reach("Pmax", "tar"), "opt": "max"},
            ],
        }),
    }
}

/// One JANI property: the query's value in the initial state.
fn property(q: &Query) -> Value {
    let comment = match &q.etp {
        Some(e) => format!("{} (etp: {e})", q.comment),
        None => q.comment.clone(),
    };
    json!({
        "name": q.name,
        "comment": comment,
        "expression": {
            "op": "filter",
            "fun": "values",
            "values": formula(&q.formula),
            "states": {"op": "initial"},
        },
    })
}

/// The JANI model of `mdp` (energy from cost model `cost`) with `queries`
/// as its properties, as a JSON value.
pub fn model(mdp: &Mdp, cost: CostModel, queries: &[Query]) -> Value {
    let n = mdp.states.len();
    let mut edges =
        Vec::with_capacity(mdp.states.iter().map(|s| s.choices.len()).sum::<usize>() + 1);
    for (i, s) in mdp.states.iter().enumerate() {
        for c in &s.choices {
            let r = c.cost(cost);
            let destinations: Vec<Value> = c
                .transitions
                .iter()
                .map(|t| {
                    json!({
                        "location": "l",
                        "probability": {"exp": t.probability},
                        "assignments": [
                            {"ref": "s", "value": target_index(mdp, t.next)},
                            {"ref": "energy", "value": r},
                        ],
                    })
                })
                .collect();
            edges.push(json!({
                "location": "l",
                "action": format!("d{}", c.action),
                "guard": {"exp": state_is(i)},
                "destinations": destinations,
            }));
        }
    }
    // The terminals loop on themselves.
    edges.push(json!({
        "location": "l",
        "action": "done",
        "guard": {"exp": {"op": "≥", "left": "s", "right": n}},
        "destinations": [{"location": "l", "assignments": []}],
    }));
    let mut actions: Vec<Value> = mdp
        .deltas
        .iter()
        .enumerate()
        .map(|(k, d)| json!({"name": format!("d{k}"), "comment": format!("threshold {d}")}))
        .collect();
    actions.push(json!({"name": "done", "comment": "a terminal's self-loop"}));
    let mut variables = vec![
        json!({
            "name": "s",
            "comment": format!("state: 0 to {} choose a threshold, {n} = coll, {} = tar, {} = free", n.saturating_sub(1), n + 1, n + 2),
            "type": {"kind": "bounded", "base": "int", "lower-bound": 0, "upper-bound": n + 2},
            "initial-value": mdp.initial,
        }),
        json!({
            "name": "energy",
            "comment": "reward: the expected energy of the choice taken",
            "type": "real",
            "transient": true,
            "initial-value": 0,
        }),
    ];
    let mut labels = Vec::new();
    for (k, label) in TERMINAL_LABELS.iter().enumerate() {
        variables.push(json!({
            "name": label,
            "type": "bool",
            "transient": true,
            "initial-value": false,
        }));
        labels.push(json!({"ref": label, "value": state_is(n + k)}));
    }
    json!({
        "jani-version": 1,
        "name": format!("etp-{}", mdp.scenario_name),
        "metadata": {
            "description": format!(
                "etp belief-space MDP of scenario \"{}\" (scenario hash {})",
                mdp.scenario_name, mdp.scenario_hash
            ),
        },
        "type": "mdp",
        "features": ["multi-objective-properties"],
        "actions": actions,
        "variables": variables,
        "properties": queries.iter().map(property).collect::<Vec<_>>(),
        "automata": [{
            "name": "etp",
            "locations": [{"name": "l", "transient-values": labels}],
            "initial-locations": ["l"],
            "edges": edges,
        }],
        "system": {"elements": [{"automaton": "etp"}]},
    })
}

/// `model.jani`: [`model`] as text.
pub fn export(mdp: &Mdp, cost: CostModel, queries: &[Query]) -> String {
    let mut text = model(mdp, cost, queries).to_string();
    text.push('\n');
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mdp::tests::toy;

    #[test]
    fn toy_jani_has_one_edge_per_choice_and_the_queries() {
        let m = toy();
        let front = crate::pareto::compute_front(&m, CostModel::Counted).expect("front");
        let q = super::super::queries(&m, &front, CostModel::Counted);
        let v = model(&m, CostModel::Counted, &q);
        let edges = v["automata"][0]["edges"].as_array().expect("edges");
        // 6 choices and the terminals' self-loop.
        assert_eq!(edges.len(), 7);
        assert_eq!(edges[1]["action"], "d1");
        assert_eq!(edges[1]["guard"]["exp"]["right"], 0);
        let d = &edges[1]["destinations"][0];
        assert_eq!(d["probability"]["exp"], 0.7);
        assert_eq!(d["assignments"][0]["value"], 2);
        assert_eq!(d["assignments"][1]["value"], 2.0);
        let props = v["properties"].as_array().expect("properties");
        assert_eq!(props.len(), q.len());
        let max = props
            .iter()
            .find(|p| p["name"] == "max_target")
            .expect("max_target");
        assert_eq!(max["expression"]["values"]["op"], "Pmax");
        assert!(
            max["comment"]
                .as_str()
                .is_some_and(|c| c.contains("etp: 0.855")),
            "{max}"
        );
        let least = props
            .iter()
            .find(|p| p["name"] == "least_energy_target")
            .expect("least_energy_target");
        let parts = &least["expression"]["values"]["properties"];
        assert_eq!(parts[0]["opt"], "min");
        assert_eq!(parts[1]["exp"]["op"], "≥");
        assert_eq!(parts[1]["exp"]["right"], 0.728);
    }
}
