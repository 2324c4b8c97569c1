//! What crosses the link between the agent's host and a sensor, split the
//! way a deployment would see it: **radio** traffic a real sensor network
//! transmits (measurements up; the belief handover down, once per leg, and
//! the ACK of each received measurement) and
//! **simulation plumbing** that stands in for the physical world or drives
//! the simulation (the true state, the slot clock, thresholds and their
//! ledgers, hello). Sizes are those of a message as the Zenoh bridge
//! carries it: its sender's time and its payload in the link encoding
//! (`super::stamp::link_frame`).

use super::{Kind, KindVisitor, Message, ServiceId};
use serde::{Deserialize, Serialize};

pub use super::catalogue::{Class, Direction};

/// The sensor-link services: class and direction, from the service's
/// catalogue row (`None`: the service never reaches a sensor — control,
/// waypoint, outcome, the wake-up events — and never crosses hosts).
pub fn link_class(s: ServiceId) -> Option<(Class, Direction)> {
    let row = s.kind()?.row();
    Some((row.link.class()?, row.forward.direction()?.0))
}

/// Bytes of one message of `kind` on the sensor link: its sender's time
/// ([`super::stamp::LINK_TIME_BYTES`]) and its payload (fixed: every payload
/// is a fixed-size struct and the link's bincode encoding uses fixed-width
/// integers; a recording's protobuf is not fixed-size).
pub fn encoded_size(kind: Kind) -> usize {
    struct Size;
    impl KindVisitor for Size {
        type Out = usize;
        fn visit<T: Message>(self) -> usize {
            // A default payload encodes to the same length as any other.
            crate::recording::Encoding::Bincode
                .encode(&T::default())
                .map_or(0, |b| super::stamp::LINK_TIME_BYTES + b.len())
        }
    }
    kind.visit(Size)
}

/// Messages and bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Count {
    pub messages: u64,
    pub bytes: u64,
}

impl Count {
    pub fn add(&mut self, messages: u64, bytes_each: u64) {
        self.messages += messages;
        self.bytes += messages * bytes_each;
    }
}

/// One sensor's link traffic, per direction and class.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkTraffic {
    pub down_radio: Count,
    pub down_plumbing: Count,
    pub up_radio: Count,
    pub up_plumbing: Count,
}

impl LinkTraffic {
    /// Count `messages` of service `s` (ignored if it is not a sensor link).
    pub fn add(&mut self, s: ServiceId, messages: u64, bytes_each: u64) {
        let slot = match link_class(s) {
            Some((Class::Radio, Direction::Down)) => &mut self.down_radio,
            Some((Class::Plumbing, Direction::Down)) => &mut self.down_plumbing,
            Some((Class::Radio, Direction::Up)) => &mut self.up_radio,
            Some((Class::Plumbing, Direction::Up)) => &mut self.up_plumbing,
            None => return,
        };
        slot.add(messages, bytes_each);
    }

    /// What one sensor's link carries in a run, from its counts: `legs`
    /// served (each: OPEN, CLOSE, ledger, and a handover when the sensor was
    /// alive at its start), `slots` (each: truth, slot), `delivered`
    /// measurements (each ACKed; an attempt lost on the radio never reaches
    /// the link's other end), plus the hello and the final STOP.
    pub fn expected(legs: u64, handovers: u64, slots: u64, delivered: u64) -> Self {
        let size = |s: ServiceId| s.kind().map_or(0, encoded_size) as u64;
        let mut t = Self::default();
        t.add(
            ServiceId::Handover(0),
            handovers,
            size(ServiceId::Handover(0)),
        );
        t.add(ServiceId::Truth(0), slots, size(ServiceId::Truth(0)));
        t.add(
            ServiceId::Threshold(0),
            2 * legs + 1,
            size(ServiceId::Threshold(0)),
        );
        t.add(
            ServiceId::Measurement,
            delivered,
            size(ServiceId::Measurement),
        );
        t.add(ServiceId::Ack(0), delivered, size(ServiceId::Ack(0)));
        t.add(ServiceId::Slot, slots, size(ServiceId::Slot));
        t.add(ServiceId::Ledger, legs, size(ServiceId::Ledger));
        t.add(ServiceId::Hello, 1, size(ServiceId::Hello));
        t
    }

    /// The downlink a per-step prior (the design before the replica: the
    /// agent sent x̂⁻, P⁻ every slot) would have needed instead of the
    /// handovers: one belief per slot.
    pub fn per_step_prior(slots: u64) -> Count {
        let mut c = Count::default();
        c.add(slots, encoded_size(Kind::Handover) as u64);
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_those_of_the_encoded_structs() {
        // The sender's time 8 B, header 32 B; handover: dim, pad, 6 + 36 f64.
        assert_eq!(encoded_size(Kind::Handover), 8 + 32 + 8 + 42 * 8);
        // Measurement: dim, sequence, 6 f64.
        assert_eq!(encoded_size(Kind::Measurement), 8 + 32 + 8 + 48);
        assert_eq!(encoded_size(Kind::Slot), 8 + 32 + 8 + 8);
    }

    #[test]
    fn every_sensor_link_service_is_classed_and_the_rest_is_not() {
        for s in ServiceId::all_pubsub(2) {
            let classed = link_class(s).is_some();
            let link = !matches!(
                s,
                ServiceId::Control | ServiceId::Waypoint | ServiceId::Outcome | ServiceId::Drift
            );
            assert_eq!(classed, link, "{s:?}");
        }
        let t = LinkTraffic::expected(3, 3, 40, 10);
        // Handovers and one ACK per delivered measurement.
        assert_eq!(t.down_radio.messages, 3 + 10);
        assert_eq!(t.up_radio.messages, 10);
        assert_eq!(t.down_plumbing.messages, 40 + 7);
        assert_eq!(t.up_plumbing.messages, 40 + 3 + 1);
    }
}
