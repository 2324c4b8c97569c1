//! What a bridge lets in from the link. Every sample from the network may be
//! garbage or forged, so before a message reaches a local iceoryx2 service it
//! must decode, belong to this run, come from the process its catalogue row
//! names as owner, concern a sensor this end carries, and (towards the agent)
//! be the next of its sensor's messages. Anything else is refused: counted
//! by reason, logged with its key, dropped, and never fatal. The run's
//! supervisor turns any refusal into a reported fault (`etp run` exit 5
//! without `--allow-degraded`).
//!
//! Pure: no Zenoh, no iceoryx2; the bridge feeds it decoded messages.

use etp_runtime::recording::Recorded;
use etp_runtime::wire::catalogue::Process;
use etp_runtime::wire::{Header, SENDER_AGENT, SENDER_COORDINATOR, ServiceId};
use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};

/// Why a message from the link was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Refusal {
    /// Its key names no service this end delivers.
    UnknownKey,
    /// Its bytes are not a payload of its key's kind.
    Malformed,
    /// Its header carries another run's tag.
    OtherRun,
    /// Its sender is not the process that owns its kind, or not a sensor
    /// this link carries (a remote sensor cannot speak for a local one).
    WrongSender,
    /// A sequence number already delivered: a replay, a duplicate, or a
    /// second host claiming the sensor.
    Duplicate,
    /// A sequence number too far ahead of the sensor's next one.
    OutOfWindow,
    /// A second host claimed a sensor another host serves (at join).
    DuplicateHost,
}

impl Refusal {
    /// The name in the bridge's report and in `etp run`'s faults.
    pub const fn name(self) -> &'static str {
        match self {
            Self::UnknownKey => "unknown-key",
            Self::Malformed => "malformed",
            Self::OtherRun => "other-run",
            Self::WrongSender => "wrong-sender",
            Self::Duplicate => "duplicate",
            Self::OutOfWindow => "out-of-window",
            Self::DuplicateHost => "duplicate-host",
        }
    }
}

/// How far ahead of a sensor's next sequence number a message is held
/// (a sensor has a few messages in flight per step; this is thousands of
/// steps of slack, and bounds what a forger can make the bridge hold).
pub const WINDOW: u32 = 4096;

/// A message that passed, with its sender's time (any number: it is only
/// recorded, never checked or ordered by) and its size on the wire.
#[derive(Debug, Clone)]
pub struct Admitted {
    pub service: ServiceId,
    pub message: Recorded,
    pub publish_time: etp_runtime::wire::stamp::PublishTime,
    pub bytes: usize,
}

/// The messages of one sensor towards the agent, in the order the sensor
/// sent them: its header's `seq` counts every message it publishes (hello
/// first, all of them forwarded), so a message that overtook another on the
/// link waits here for it.
#[derive(Debug, Default)]
struct SensorOrder {
    /// The next sequence number to deliver (the hello is 1).
    next: u32,
    held: BTreeMap<u32, Admitted>,
    /// Since when (as the caller's clock last told [`Admission::gaps`]) a
    /// gap holds messages back.
    gap_since: Option<Instant>,
    /// Cut by the agent host (a dead link): nothing more is delivered.
    cut: bool,
}

/// A gap in a sensor's sequence numbers that held its later messages back
/// longer than the bound ([`Admission::gaps`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    pub sensor: usize,
    /// The sequence number that never came.
    pub missing: u32,
    /// How many later messages it held back.
    pub held: usize,
    /// The first of them: its service and header.
    pub first_held: (ServiceId, Header),
    /// How long they waited.
    pub waited: Duration,
}

/// The checks of one end of a link.
#[derive(Debug)]
pub struct Admission {
    tag: u64,
    /// The sensors whose messages this end carries.
    sensors: BTreeSet<usize>,
    /// Towards the agent: per sensor, its messages in send order.
    order: Option<BTreeMap<usize, SensorOrder>>,
    refused: BTreeMap<Refusal, u64>,
    /// Messages that arrived before an earlier one of their sensor and
    /// waited for it (not a fault: the link overtook).
    reordered: u64,
    /// Towards the agent: the host each remote sensor was granted to at
    /// join (its Zenoh id), first claim wins.
    hosts: BTreeMap<usize, String>,
    /// Messages of cut sensors dropped (held at the cut, or arrived later).
    after_cut: u64,
}

/// The longest host identity a claim may carry (a Zenoh id is at most 32
/// hexadecimal digits).
pub const MAX_HOST_ID: usize = 64;

impl Admission {
    /// The agent host's end: messages of the remote `sensors`, each sensor's
    /// in its send order.
    pub fn towards_agent(tag: u64, sensors: &[usize]) -> Self {
        Self {
            tag,
            sensors: sensors.iter().copied().collect(),
            order: Some(
                sensors
                    .iter()
                    .map(|&i| {
                        (
                            i,
                            SensorOrder {
                                next: 1,
                                ..SensorOrder::default()
                            },
                        )
                    })
                    .collect(),
            ),
            refused: BTreeMap::new(),
            reordered: 0,
            hosts: BTreeMap::new(),
            after_cut: 0,
        }
    }

    /// A sensor host's end: the agent's and coordinator's messages for the
    /// `served` sensors.
    pub fn towards_sensors(tag: u64, served: &[usize]) -> Self {
        Self {
            tag,
            sensors: served.iter().copied().collect(),
            order: None,
            refused: BTreeMap::new(),
            reordered: 0,
            hosts: BTreeMap::new(),
            after_cut: 0,
        }
    }

    /// Who may send a message of `service` with header `h`: its row's owner
    /// (a sensor only about itself, on a link that carries it).
    fn sender_ok(&self, service: ServiceId, h: &Header) -> bool {
        let Some(kind) = service.kind() else {
            return false;
        };
        let about = service.sensor();
        if about.is_some_and(|i| !self.sensors.contains(&i)) {
            return false;
        }
        match kind.row().owner {
            Process::Coordinator => h.sender == SENDER_COORDINATOR,
            Process::Agent => h.sender == SENDER_AGENT,
            // Towards the agent only sensors speak (a sensor's hello included).
            Process::Sensor | Process::Any => {
                let sender = h.sender as usize;
                self.order.is_some()
                    && self.sensors.contains(&sender)
                    && about.is_none_or(|i| i == sender)
            }
        }
    }

    /// Check a decoded message; the messages now deliverable, in order
    /// (none while it waits for an earlier one).
    pub fn admit(&mut self, m: Admitted) -> Result<Vec<Admitted>, Refusal> {
        let h = *m.message.header();
        let checked = if h.run != self.tag {
            Err(Refusal::OtherRun)
        } else if !self.sender_ok(m.service, &h) {
            Err(Refusal::WrongSender)
        } else {
            Ok(())
        };
        if let Err(r) = checked {
            return Err(self.refuse(r));
        }
        let Some(order) = self.order.as_mut() else {
            return Ok(vec![m]);
        };
        let Some(o) = order.get_mut(&(h.sender as usize)) else {
            return Err(self.refuse(Refusal::WrongSender));
        };
        if o.cut {
            // A dead link's late traffic: not a refusal, not delivered.
            self.after_cut += 1;
            return Ok(Vec::new());
        }
        if h.seq < o.next || o.held.contains_key(&h.seq) {
            return Err(self.refuse(Refusal::Duplicate));
        }
        if h.seq - o.next >= WINDOW {
            return Err(self.refuse(Refusal::OutOfWindow));
        }
        if h.seq != o.next {
            self.reordered += 1;
        }
        o.held.insert(h.seq, m);
        let mut ready = Vec::new();
        while let Some(m) = o.held.remove(&o.next) {
            ready.push(m);
            o.next = o.next.wrapping_add(1);
        }
        Ok(ready)
    }

    /// A host's claim, at join, to serve remote sensor `sensor`: granted to
    /// the first host that claims it (again to the same host, which may
    /// ask twice), refused for any other (`DuplicateHost`: one sensor, one
    /// process, one stream of sequence numbers). A claim of a sensor this
    /// end does not carry is `WrongSender`; a host id that is empty, too
    /// long or not plain ASCII alphanumerics is `Malformed`. Every refusal
    /// is counted: a fault of the run.
    pub fn claim(&mut self, sensor: usize, host: &str) -> Result<(), Refusal> {
        if host.is_empty()
            || host.len() > MAX_HOST_ID
            || !host.bytes().all(|b| b.is_ascii_alphanumeric())
        {
            return Err(self.refuse(Refusal::Malformed));
        }
        if self.order.is_none() || !self.sensors.contains(&sensor) {
            return Err(self.refuse(Refusal::WrongSender));
        }
        match self.hosts.get(&sensor) {
            None => {
                self.hosts.insert(sensor, host.to_string());
                Ok(())
            }
            Some(h) if h == host => Ok(()),
            Some(_) => Err(self.refuse(Refusal::DuplicateHost)),
        }
    }

    /// Count a refusal made outside [`Self::admit`] (an unknown key, bytes
    /// that do not decode); returns it.
    pub fn refuse(&mut self, r: Refusal) -> Refusal {
        *self.refused.entry(r).or_default() += 1;
        r
    }

    /// Refusals so far, by reason.
    pub fn refused(&self) -> &BTreeMap<Refusal, u64> {
        &self.refused
    }

    /// Messages that waited for an earlier one of their sensor.
    pub fn reordered(&self) -> u64 {
        self.reordered
    }

    /// Look at the gaps at `now` (the caller's clock; called at least every
    /// few hundred milliseconds): the oldest gap that has held its sensor's
    /// later messages for `bound` or longer. A gap's age counts from the
    /// first call that saw it, so it is late by at most the calling period.
    pub fn gaps(&mut self, now: Instant, bound: Duration) -> Option<Gap> {
        let order = self.order.as_mut()?;
        let mut oldest: Option<Gap> = None;
        for (&sensor, o) in order.iter_mut() {
            let first = o.held.first_key_value().map(|(_, m)| m);
            let Some(first) = first.filter(|_| !o.cut) else {
                o.gap_since = None;
                continue;
            };
            let since = *o.gap_since.get_or_insert(now);
            let waited = now.saturating_duration_since(since);
            if waited >= bound && oldest.as_ref().is_none_or(|g| waited > g.waited) {
                oldest = Some(Gap {
                    sensor,
                    missing: o.next,
                    held: o.held.len(),
                    first_held: (first.service, *first.message.header()),
                    waited,
                });
            }
        }
        oldest
    }

    /// The agent host cut `sensor` (a dead link): what it held is dropped
    /// and nothing of it is delivered from now on.
    pub fn cut(&mut self, sensor: usize) {
        if let Some(o) = self.order.as_mut().and_then(|m| m.get_mut(&sensor)) {
            self.after_cut += o.held.len() as u64;
            o.held.clear();
            o.gap_since = None;
            o.cut = true;
        }
    }

    /// Messages of cut sensors dropped.
    pub fn after_cut(&self) -> u64 {
        self.after_cut
    }

    /// Messages held for an earlier one that never came (per sensor).
    pub fn held(&self) -> BTreeMap<usize, usize> {
        self.order
            .iter()
            .flatten()
            .filter(|(_, o)| !o.held.is_empty())
            .map(|(&i, o)| (i, o.held.len()))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::messages::{sensor_to_agent as s2a, sensor_to_coordinator as s2c};
    use etp_runtime::wire::{Message, messages::agent_to_sensor as a2s};

    const TAG: u64 = 0xE7;

    fn header(sender: u32, seq: u32) -> Header {
        Header {
            run: TAG,
            episode: 0,
            step: 1,
            leg: 0,
            sender,
            seq,
        }
    }

    fn measurement(sender: u32, seq: u32) -> Admitted {
        Admitted {
            service: ServiceId::Measurement,
            message: s2a::Measurement {
                header: header(sender, seq),
                ..Default::default()
            }
            .into_recorded(),
            publish_time: 0,
            bytes: 1,
        }
    }

    fn seqs(v: &[Admitted]) -> Vec<u32> {
        v.iter().map(|m| m.message.header().seq).collect()
    }

    #[test]
    fn a_sensors_messages_are_delivered_in_the_order_it_sent_them() {
        let mut a = Admission::towards_agent(TAG, &[0, 2]);
        assert_eq!(seqs(&a.admit(measurement(0, 1)).expect("next")), [1]);
        // 3 overtook 2 on the link: held until 2 comes.
        assert!(a.admit(measurement(0, 3)).expect("held").is_empty());
        assert_eq!(a.held(), BTreeMap::from([(0, 1)]));
        // Another sensor's order is its own.
        assert_eq!(seqs(&a.admit(measurement(2, 1)).expect("next")), [1]);
        assert_eq!(seqs(&a.admit(measurement(0, 2)).expect("gap")), [2, 3]);
        assert!(a.held().is_empty());
        assert!(a.refused().is_empty());
        assert_eq!(a.reordered(), 1);
    }

    /// The hang of an all-remote run (docs/MODEL.md, runtime): a message
    /// that never arrives held its sensor's later ones for ever. Now a gap
    /// is named once it held them for the bound, and a cut sensor's late
    /// traffic is dropped, counted, and never delivered.
    #[test]
    fn a_gap_is_held_no_longer_than_the_bound_then_named() {
        let bound = Duration::from_secs(5);
        let t0 = Instant::now();
        let mut a = Admission::towards_agent(TAG, &[0, 1]);
        a.admit(measurement(1, 1)).expect("next");
        assert_eq!(a.gaps(t0, bound), None);
        // Sequence number 2 of sensor 1 is lost; 3 and 4 wait for it.
        assert!(a.admit(measurement(1, 3)).expect("held").is_empty());
        assert!(a.admit(measurement(1, 4)).expect("held").is_empty());
        assert_eq!(a.gaps(t0, bound), None, "the gap is seen now");
        assert_eq!(a.gaps(t0 + bound / 2, bound), None);
        let g = a.gaps(t0 + bound, bound).expect("named at the bound");
        assert_eq!(
            (g.sensor, g.missing, g.held, g.first_held.1.seq, g.waited),
            (1, 2, 2, 3, bound)
        );
        // A gap that closes in time is forgotten.
        assert!(a.admit(measurement(0, 2)).expect("held").is_empty());
        assert_eq!(seqs(&a.admit(measurement(0, 1)).expect("closes")), [1, 2]);
        a.cut(1);
        assert_eq!(a.gaps(t0 + bound * 9, bound), None);
        assert!(a.admit(measurement(1, 2)).expect("dropped").is_empty());
        assert_eq!(a.after_cut(), 3);
        assert!(a.held().is_empty() && a.refused().is_empty());
    }

    #[test]
    fn forged_replayed_and_foreign_messages_are_refused_and_counted() {
        let mut a = Admission::towards_agent(TAG, &[0]);
        a.admit(measurement(0, 1)).expect("next");
        // A replay of a delivered message, or a second copy of a held one.
        assert_eq!(a.admit(measurement(0, 1)).err(), Some(Refusal::Duplicate));
        a.admit(measurement(0, 5)).expect("held");
        assert_eq!(a.admit(measurement(0, 5)).err(), Some(Refusal::Duplicate));
        assert_eq!(
            a.admit(measurement(0, 2 + WINDOW)).err(),
            Some(Refusal::OutOfWindow)
        );
        // Sensor 3 is local: nobody on the link speaks for it.
        assert_eq!(a.admit(measurement(3, 1)).err(), Some(Refusal::WrongSender));
        // Neither the agent nor the coordinator sends measurements.
        assert_eq!(
            a.admit(measurement(SENDER_AGENT, 1)).err(),
            Some(Refusal::WrongSender)
        );
        let mut other = measurement(0, 2);
        if let Recorded::Measurement(m) = &mut other.message {
            m.header.run = TAG + 1;
        }
        assert_eq!(a.admit(other).err(), Some(Refusal::OtherRun));
        // A ledger is a sensor's too, and it speaks only for itself.
        let ledger = Admitted {
            service: ServiceId::Ledger,
            message: s2c::Ledger {
                header: header(1, 2),
                ..Default::default()
            }
            .into_recorded(),
            publish_time: 0,
            bytes: 1,
        };
        assert_eq!(a.admit(ledger).err(), Some(Refusal::WrongSender));
        assert_eq!(
            a.refused(),
            &BTreeMap::from([
                (Refusal::OtherRun, 1),
                (Refusal::WrongSender, 3),
                (Refusal::Duplicate, 2),
                (Refusal::OutOfWindow, 1),
            ])
        );
    }

    #[test]
    fn a_sensor_is_granted_to_the_first_host_that_claims_it() {
        let mut a = Admission::towards_agent(TAG, &[1, 3]);
        assert_eq!(a.claim(1, "a1b2"), Ok(()));
        // The same host may ask again (a retried query).
        assert_eq!(a.claim(1, "a1b2"), Ok(()));
        assert_eq!(a.claim(3, "ffee"), Ok(()));
        assert_eq!(a.claim(1, "ffee"), Err(Refusal::DuplicateHost));
        // Sensor 0 is local; a host id must be a plain id.
        assert_eq!(a.claim(0, "ffee"), Err(Refusal::WrongSender));
        assert_eq!(a.claim(3, ""), Err(Refusal::Malformed));
        assert_eq!(a.claim(3, "a/b"), Err(Refusal::Malformed));
        assert_eq!(
            a.claim(3, &"a".repeat(MAX_HOST_ID + 1)),
            Err(Refusal::Malformed)
        );
        assert_eq!(
            a.refused(),
            &BTreeMap::from([
                (Refusal::Malformed, 3),
                (Refusal::WrongSender, 1),
                (Refusal::DuplicateHost, 1),
            ])
        );
        // Towards the sensors nobody claims anything.
        let mut s = Admission::towards_sensors(TAG, &[1]);
        assert_eq!(s.claim(1, "a1b2"), Err(Refusal::WrongSender));
    }

    #[test]
    fn towards_a_sensor_only_its_owners_speak_and_only_for_served_sensors() {
        let mut a = Admission::towards_sensors(TAG, &[1]);
        let handover = |sensor: usize, sender: u32| Admitted {
            service: ServiceId::Handover(sensor),
            message: a2s::Handover {
                header: header(sender, 9),
                ..Default::default()
            }
            .into_recorded(),
            publish_time: 0,
            bytes: 1,
        };
        assert_eq!(a.admit(handover(1, SENDER_AGENT)).expect("owner").len(), 1);
        assert_eq!(
            a.admit(handover(1, SENDER_COORDINATOR)).err(),
            Some(Refusal::WrongSender)
        );
        assert_eq!(
            a.admit(handover(0, SENDER_AGENT)).err(),
            Some(Refusal::WrongSender),
            "sensor 0 is not served here"
        );
        // Sensors do not speak towards sensors.
        assert_eq!(a.admit(measurement(1, 1)).err(), Some(Refusal::WrongSender));
    }
}
