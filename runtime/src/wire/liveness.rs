//! Nodes of a run and their liveness: the node names of the processes,
//! creating a node, and what the run's node list says about one (alive,
//! dead — its stale resources removed on the way — or missing).

use super::{RunId, WireError, config};
use iceoryx2::config::Config;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// Node names of the run's processes (used for liveness checks).
pub const COORDINATOR_NODE: &str = "etp-coordinator";
pub const AGENT_NODE: &str = "etp-agent";
/// Node name of the recorder (`etp run --record`), started before the others.
pub const RECORDER_NODE: &str = "etp-recorder";
/// Node name of sensor `i`.
pub fn sensor_node_name(i: usize) -> String {
    format!("etp-sensor-{i}")
}

/// Create a node of a run. iceoryx2 signal handling is off: the processes poll
/// their own termination flag (see the binaries), and tokio owns signals in `etp`.
pub fn create_node(run: &RunId, name: &str) -> Result<Node<ipc::Service>, WireError> {
    let cfg = config(run)?;
    let nname = NodeName::new(name).map_err(|e| WireError::Node(format!("name {name}: {e:?}")))?;
    let node = NodeBuilder::new()
        .name(&nname)
        .config(&cfg)
        .create::<ipc::Service>()
        .map_err(|e| WireError::Node(format!("{e:?}")))?;
    // Installs iceoryx2's SIGINT/SIGTERM handler now (it is lazy): until a
    // process's first wait, a SIGTERM would otherwise kill it outright.
    super::termination_requested(&node);
    Ok(node)
}

/// What the node list says about a named node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveness {
    Alive,
    /// Its process died (its stale resources were removed just now).
    Dead,
    /// No such node (never started, or already cleaned up).
    Missing,
}

/// Look a node up by name in the run's node list; a dead node's stale
/// resources are removed on the way (so the peers' counts drop and listeners
/// get [`super::ports::DEAD_NOTIFIER_EVENT`]).
pub fn liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, true)
}

/// [`liveness`] without the cleanup: the verdict only, as fast as the node
/// list can give it (the cleanup of a dead node's ports can take tens of
/// milliseconds; call [`remove_dead_nodes`] afterwards).
pub fn peek_liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, false)
}

fn node_state(cfg: &Config, name: &str, cleanup: bool) -> Liveness {
    let named = |d: &Option<iceoryx2::node::NodeDetails>| {
        d.as_ref().is_some_and(|d| d.name().as_str() == name)
    };
    let mut found = Liveness::Missing;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        match state {
            NodeState::Alive(view) if named(view.details()) => found = Liveness::Alive,
            NodeState::Dead(view) if named(view.details()) => {
                found = Liveness::Dead;
                if cleanup {
                    let _ = view.try_remove_stale_resources();
                }
            }
            _ => return CallbackProgression::Continue,
        }
        CallbackProgression::Stop
    });
    found
}

/// Remove what dead nodes of a run left behind; returns how many were removed.
pub fn remove_dead_nodes(cfg: &Config) -> usize {
    let mut removed = 0;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            removed += 1;
        }
        CallbackProgression::Continue
    });
    removed
}

/// Number of live nodes of a run.
pub fn alive_nodes(cfg: &Config) -> usize {
    let mut alive = 0;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Alive(_) = state {
            alive += 1;
        }
        CallbackProgression::Continue
    });
    alive
}
