//! The services of a run, derived from the catalogue's rows: each
//! [`ServiceId`]'s name and topic, the wake-up event its reader is notified
//! on, every service a recorder subscribes to, and what a bridge forwards
//! for remote sensors. Nothing here names a message: a new row of
//! `super::catalogue` gets all of it.

pub use super::catalogue::ServiceId;

use super::RunId;
use super::catalogue::{Direction, Kind, Process};

/// The index placeholder of a per-sensor topic pattern.
const SENSOR: &str = "{sensor}";

impl ServiceId {
    /// The service name `etp/<run-id>/<topic>`.
    pub fn name(&self, run: &RunId) -> String {
        format!("etp/{run}/{}", self.topic())
    }

    /// The service's name within its run (also its recording's channel
    /// topic): `control`, `sensor/3/truth`, …
    pub fn topic(&self) -> String {
        match (self.kind(), self.sensor()) {
            (Some(k), Some(i)) => k.row().topic.replace(SENSOR, &i.to_string()),
            (Some(k), None) => k.row().topic.to_string(),
            (None, Some(i)) => format!("sensor/{i}/wake"),
            (None, None) if *self == Self::AgentWake => "agent/wake".to_string(),
            (None, None) => "coordinator/wake".to_string(),
        }
    }

    /// The wake-up event its reader is notified on after a publication
    /// (itself for an event). `replay publish` notifies the same events as
    /// the live processes did, so observers (the recorder) wake alike.
    pub fn reader_wake(self) -> Self {
        let Some(kind) = self.kind() else {
            return self;
        };
        match (kind.row().reader, self.sensor()) {
            (Process::Agent, _) => Self::AgentWake,
            (Process::Sensor, Some(i)) => Self::SensorWake(i),
            // The catalogue's const checks: a sensor reads only per-sensor
            // services, and `any` is never a reader.
            (Process::Coordinator | Process::Sensor | Process::Any, _) => Self::CoordinatorWake,
        }
    }

    /// Every wake-up event of a run: every publication is followed by a
    /// notification on one of them, so an observer (the recorder) listening
    /// to all of them wakes whenever there is something to read.
    pub fn all_events(sensors: usize) -> Vec<Self> {
        let mut v = vec![Self::AgentWake, Self::CoordinatorWake];
        v.extend((0..sensors).map(Self::SensorWake));
        v
    }

    /// Every publish-subscribe service of a run with `sensors` sensors: the
    /// shared ones in catalogue order, then each sensor's.
    pub fn all_pubsub(sensors: usize) -> Vec<Self> {
        let shared = Kind::ALL
            .iter()
            .filter_map(|&k| Self::of(k, None))
            .collect::<Vec<_>>();
        let per_sensor =
            (0..sensors).flat_map(|i| Kind::ALL.iter().filter_map(move |&k| Self::of(k, Some(i))));
        shared.into_iter().chain(per_sensor).collect()
    }

    /// The services a recorder subscribes to (the recorded rows).
    pub fn recorded(sensors: usize) -> Vec<Self> {
        Self::all_pubsub(sensors)
            .into_iter()
            .filter(|s| s.kind().is_some_and(|k| k.row().recorded))
            .collect()
    }

    /// What a bridge carries in `direction` for the remote sensors `remote`:
    /// the shared services, then each remote sensor's own, each group in
    /// causal rank (a message after those it may depend on: the OPEN before
    /// the handover before the truth; a measurement before its slot).
    pub fn forwarded(direction: Direction, remote: &[usize]) -> Vec<Self> {
        let mut rows: Vec<(u8, Kind)> = Kind::ALL
            .iter()
            .filter_map(|&k| match k.row().forward.direction() {
                Some((d, rank)) if d == direction => Some((rank, k)),
                _ => None,
            })
            .collect();
        rows.sort();
        let shared = rows.iter().filter_map(|&(_, k)| Self::of(k, None));
        let own = remote
            .iter()
            .flat_map(|&i| rows.iter().filter_map(move |&(_, k)| Self::of(k, Some(i))));
        shared.chain(own).collect()
    }

    /// The wake-up events the publishers of `services` notify (each once,
    /// in order of first appearance): what a forwarder listens to.
    pub fn wakes_of(services: &[Self]) -> Vec<Self> {
        let mut v: Vec<Self> = Vec::new();
        for w in services.iter().map(|s| s.reader_wake()) {
            if !v.contains(&w) {
                v.push(w);
            }
        }
        v
    }

    /// The inverse of [`ServiceId::topic`] for publish-subscribe services
    /// (canonical spelling only: `sensor/01/truth` is not a topic).
    pub fn from_topic(topic: &str) -> Option<Self> {
        Kind::ALL.iter().find_map(|&k| {
            let pattern = k.row().topic;
            let s = match pattern.split_once(SENSOR) {
                None => Self::of(k, None).filter(|_| pattern == topic)?,
                Some((head, tail)) => {
                    let index = topic.strip_prefix(head)?.strip_suffix(tail)?;
                    // Digits only: `usize::from_str` would take a `+`.
                    if !index.bytes().all(|b| b.is_ascii_digit()) {
                        return None;
                    }
                    Self::of(k, Some(index.parse().ok()?))?
                }
            };
            (s.topic() == topic).then_some(s)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::catalogue::{Class, Forward, KindVisitor, LimitsClass, Link, Message};
    use super::super::limits::limits;
    use super::super::traffic::link_class;
    use super::*;

    #[test]
    fn every_service_has_one_topic_and_kind() {
        for s in ServiceId::all_pubsub(12) {
            assert_eq!(ServiceId::from_topic(&s.topic()), Some(s));
            assert!(s.kind().is_some(), "{s:?}");
        }
        for bad in [
            "",
            "sensor/x/truth",
            "sensor/1/wake",
            "sensor//handover",
            "sensor/01/truth",
            "sensor/+1/truth",
            "nope",
        ] {
            assert_eq!(ServiceId::from_topic(bad), None, "{bad}");
        }
        // Twelve messages, and this crate's test-only probe.
        assert_eq!(Kind::ALL.len(), 13);
    }

    /// Every row has every column, and the columns agree: a per-sensor
    /// topic is `sensor/{sensor}/…` (a sensor host subscribes to
    /// `…/down/sensor/<i>/**`), a shared one has no placeholder; the codes
    /// are written; ranks are unique per direction.
    #[test]
    fn every_row_has_every_column_and_they_agree() {
        let mut ranks = std::collections::BTreeSet::new();
        for &k in Kind::ALL {
            let r = k.row();
            assert_eq!(r.kind, k);
            assert!(!r.topic.is_empty(), "{k:?}");
            assert_eq!(r.per_sensor, r.topic.contains(SENSOR), "{k:?}");
            if r.per_sensor {
                assert!(r.topic.starts_with("sensor/{sensor}/"), "{k:?}");
            }
            assert!(!r.codes.is_empty(), "{k:?}");
            assert_ne!(r.reader, Process::Any, "{k:?}");
            assert_eq!(r.link.class().is_some(), r.forward != Forward::Local);
            if let Some(d) = r.forward.direction() {
                assert!(ranks.insert((d.0 == Direction::Down, d.1)), "{k:?}");
            }
        }
    }

    /// Each payload's iceoryx2 type name (its `#[type_name(..)]`, which
    /// iceoryx2 checks when a port opens and a recording names its schema
    /// by) is its kind's schema name: a struct renamed in one place only
    /// fails here, not between two processes.
    #[test]
    fn each_payloads_type_name_is_its_kinds_schema_name() {
        struct TypeNameOf;
        impl KindVisitor for TypeNameOf {
            type Out = &'static str;
            #[allow(unsafe_code)]
            fn visit<T: Message>(self) -> &'static str {
                // SAFETY: reading the name has no precondition; the trait's
                // contract (the same layout in every process) binds its
                // implementors, here the derive on each payload.
                unsafe { <T as iceoryx2::prelude::ZeroCopySend>::type_name() }
            }
        }
        for &k in Kind::ALL {
            assert_eq!(k.visit(TypeNameOf), k.schema_name(), "{k:?}");
        }
    }

    #[test]
    fn the_bridge_lists_are_those_of_before_the_catalogue_held_them() {
        use ServiceId as S;
        assert_eq!(
            ServiceId::forwarded(Direction::Up, &[1, 3]),
            [S::Hello, S::Measurement, S::Slot, S::Ledger]
        );
        let down = ServiceId::forwarded(Direction::Down, &[1, 3]);
        // Causal order per sensor; the test-only probe comes last.
        assert_eq!(
            down,
            [
                S::Threshold(1),
                S::Handover(1),
                S::Ack(1),
                S::Truth(1),
                S::Probe(1),
                S::Threshold(3),
                S::Handover(3),
                S::Ack(3),
                S::Truth(3),
                S::Probe(3)
            ]
        );
        assert_eq!(
            ServiceId::wakes_of(&down),
            [S::SensorWake(1), S::SensorWake(3)]
        );
        assert_eq!(
            ServiceId::wakes_of(&ServiceId::forwarded(Direction::Up, &[0])),
            [S::CoordinatorWake, S::AgentWake]
        );
    }

    #[test]
    fn recorded_services_keep_the_order_of_the_recordings() {
        use ServiceId as S;
        let r = ServiceId::recorded(2);
        let expected = [
            S::Control,
            S::Measurement,
            S::Slot,
            S::Waypoint,
            S::Outcome,
            S::Ledger,
            S::Hello,
            S::Drift,
            S::Threshold(0),
            S::Truth(0),
            S::Handover(0),
            S::Ack(0),
            S::Probe(0),
            S::Threshold(1),
            S::Truth(1),
            S::Handover(1),
            S::Ack(1),
            S::Probe(1),
        ];
        assert_eq!(r, expected);
    }

    /// The test-only row (`Probe`, `#[cfg(test)]` in the catalogue) gets
    /// everything from its one row: a service per sensor with its topic and
    /// the way back, the reader's wake-up, limits, the recorder's
    /// subscription, its link class, forwarding, a schema and a round trip
    /// through the recording's encoding.
    #[test]
    fn a_test_only_row_derives_everything() {
        use super::super::messages::test_only::Probe;
        let s = ServiceId::Probe(4);
        assert_eq!(s.kind(), Some(Kind::Probe));
        assert_eq!(s.sensor(), Some(4));
        assert_eq!(s.topic(), "sensor/4/probe");
        assert_eq!(ServiceId::from_topic("sensor/4/probe"), Some(s));
        assert_eq!(s.reader_wake(), ServiceId::SensorWake(4));
        assert!(ServiceId::all_pubsub(5).contains(&s));
        assert!(ServiceId::recorded(5).contains(&s));
        assert_eq!(link_class(s), Some((Class::Radio, Direction::Down)));
        assert!(ServiceId::forwarded(Direction::Down, &[4]).contains(&s));
        assert!(!ServiceId::forwarded(Direction::Up, &[4]).contains(&s));
        assert_eq!(Kind::Probe.row().limits, LimitsClass::OneToOne(8));
        assert_eq!(Kind::Probe.row().link, Link::Radio);
        assert_eq!(limits(s, 3), limits(ServiceId::Truth(4), 3));
        let text = Kind::Probe.schema_text();
        assert!(
            text.starts_with("# etp::Probe (bincode2-serde-legacy), published by the agent\n"),
            "{text}"
        );
        assert!(text.contains("flag: u32\n"), "{text}");
        let p = Probe {
            flag: 1,
            ..Probe::default()
        };
        let bytes = crate::recording::encode(&p).expect("encodes");
        assert_eq!(
            crate::recording::decode("sensor/4/probe", &bytes).expect("decodes"),
            super::super::Recorded::Probe(p)
        );
        assert_eq!(Kind::Probe.proto_name(), "etp.Probe");
    }
}
