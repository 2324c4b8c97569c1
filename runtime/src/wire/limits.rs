//! THE limits table: how many ports, nodes and buffered samples each
//! service allows, from its catalogue row's limits class and the run's
//! number of sensors.

use super::ServiceId;
use super::catalogue::LimitsClass;

/// The limits of one service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    pub max_publishers: usize,
    pub max_subscribers: usize,
    pub max_nodes: usize,
    /// Buffer of the run's own subscribers.
    pub buffer: usize,
    /// Buffer of an observer's (the recorder's) subscriber; the service's
    /// maximum is the larger of the two.
    pub observer_buffer: usize,
    pub history: usize,
    /// Off for every service that carries data, control or accounting: a
    /// full buffer (a slow, paused or lagging reader, the recorder included)
    /// makes the publisher wait instead of overwriting an unread sample. On
    /// only for the wake-up events, which carry nothing.
    pub safe_overflow: bool,
}

/// Buffer of the recorder's subscribers (it drains whenever a wake-up event fires).
const OBSERVER_BUFFER: usize = 512;

/// Extra ports and nodes every service allows beyond the run's own processes:
/// a recorder and a replayer.
const OBSERVERS: usize = 2;

/// THE limits table: every process opens every service through
/// [`super::open_pubsub`] / [`super::open_event`], which take their limits from here, so whichever process
/// creates a service first, it has the same QoS (the iceoryx2 defaults —
/// 2 publishers, 20 nodes, 16 notifiers — fail at 32 sensors).
pub fn limits(service: ServiceId, sensors: usize) -> Limits {
    let nodes = sensors + 2 + OBSERVERS;
    let one_to_one = |buffer| Limits {
        max_publishers: 1 + OBSERVERS,
        max_subscribers: 1 + OBSERVERS,
        max_nodes: nodes,
        buffer,
        observer_buffer: OBSERVER_BUFFER,
        history: 0,
        safe_overflow: false,
    };
    let many_to_one = |buffer| Limits {
        max_publishers: sensors + OBSERVERS,
        ..one_to_one(buffer)
    };
    let Some(kind) = service.kind() else {
        // The wake-up events carry nothing: overflow is safe.
        let event = |max_publishers| Limits {
            max_publishers,
            max_subscribers: 1 + OBSERVERS,
            max_nodes: nodes,
            buffer: 0,
            observer_buffer: 0,
            history: 0,
            safe_overflow: true,
        };
        return match service {
            // Woken by the agent and the coordinator (and observers).
            ServiceId::SensorWake(_) => event(2 + OBSERVERS),
            // Woken by every process.
            _ => event(sensors + 2 + OBSERVERS),
        };
    };
    match kind.row().limits {
        LimitsClass::OneToOne(buffer) => one_to_one(buffer),
        LimitsClass::OneToTwo(buffer) => Limits {
            max_subscribers: 2 + OBSERVERS,
            ..one_to_one(buffer)
        },
        LimitsClass::FromSensors(buffer) => many_to_one(buffer),
        // Late subscribers (the coordinator starts in parallel) get the history.
        LimitsClass::Announce => Limits {
            max_publishers: sensors + 2 + OBSERVERS,
            max_subscribers: 1 + OBSERVERS,
            max_nodes: nodes,
            buffer: sensors + 4,
            observer_buffer: sensors + 4,
            history: 1,
            safe_overflow: false,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_admit_32_sensors_and_a_recorder() {
        for s in ServiceId::all_pubsub(32) {
            let l = limits(s, 32);
            assert!(l.max_nodes > 32 + 2);
            assert!(l.max_subscribers >= 2);
        }
        assert!(limits(ServiceId::Measurement, 32).max_publishers >= 33);
        assert!(limits(ServiceId::Threshold(31), 32).max_subscribers > 2);
        // Nothing that carries data or accounting may overwrite an unread sample.
        for s in ServiceId::all_pubsub(32) {
            assert!(!limits(s, 32).safe_overflow, "{s:?}");
        }
        assert!(limits(ServiceId::AgentWake, 32).max_publishers >= 34);
    }
}
