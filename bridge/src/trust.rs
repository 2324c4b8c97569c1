//! What the agent host lets in from the link: nothing a remote sensor's host
//! could not have said (pure: no I/O, the clock passed in).
//!
//! Every up message (decoded already; malformed bytes never get here) must
//! * carry the run's tag;
//! * come from a *remote* sensor (a host cannot speak for a local one), one
//!   its host may serve (`hosts.json` under TLS), claimed by that host — the
//!   first host whose hello or liveliness token names the sensor claims it,
//!   a second one is refused (duplicate sensor host);
//! * be the next of that sensor's per-sender sequence numbers: a sensor
//!   numbers every message it sends (hello, measurements, slots, ledgers)
//!   1, 2, 3, …; one arriving early is held until the gap fills (bounded in
//!   count and time), one already seen is a replay;
//! * answer something asked: a measurement or slot only for an (episode,
//!   step) whose truth went down to that sensor and whose slot is still
//!   open; a ledger only for a leg it served and has not closed.
//!
//! Anything else is a [`Refusal`]: reported, never delivered, never fatal.

use etp_runtime::recording::Recorded;
use etp_runtime::wire::{Header, ServiceId};
use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Why a message from the link was not let in.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Refusal {
    /// `malformed`, `wrong-run`, `not-remote`, `not-allowed`,
    /// `duplicate-host`, `not-claimant`, `replayed`, `gap`, `not-asked`.
    pub kind: &'static str,
    /// The sending host (as named in the key).
    pub host: String,
    pub sensor: Option<usize>,
    pub detail: String,
}

/// A message let in, to deliver in this order.
pub type Delivery = (ServiceId, Recorded, usize);

/// How many early messages of one sensor are held, and how long its stream
/// may stand still on a missing one before that is declared lost (only a
/// sensor with no progress for that long: a message forged far ahead of the
/// stream never makes a live sensor's stream jump).
pub const MAX_HELD: usize = 1024;
pub const GAP_WAIT: Duration = Duration::from_secs(2);

/// What the agent host asked of each remote sensor (written by the
/// outbound direction *before* it puts a truth, read by the inbound one).
#[derive(Debug, Default, Clone)]
pub struct Asked(Arc<Mutex<BTreeMap<usize, AskedOf>>>);

#[derive(Debug, Default)]
pub struct AskedOf {
    /// (episode, step) of truths sent whose slot has not come back.
    steps: BTreeSet<(u64, u32)>,
    /// (episode, leg) served whose ledger has not come back.
    legs: BTreeSet<(u64, u32)>,
}

impl Asked {
    /// Note a down message to sensor `i` about to be put.
    pub fn note(&self, s: ServiceId, h: &Header) {
        let i = match s {
            ServiceId::Truth(i) | ServiceId::Threshold(i) | ServiceId::Handover(i) => i,
            _ => return,
        };
        if let Ok(mut m) = self.0.lock() {
            let a = m.entry(i).or_default();
            if matches!(s, ServiceId::Truth(_)) {
                a.steps.insert((h.episode, h.step));
            }
            a.legs.insert((h.episode, h.leg));
        }
    }

    /// Was message `s` of sensor `i` asked for? (Consumes a slot or ledger.)
    fn answers(&self, i: usize, s: ServiceId, h: &Header) -> bool {
        let Ok(mut m) = self.0.lock() else {
            return false;
        };
        let a = m.entry(i).or_default();
        match s {
            ServiceId::Measurement => a.steps.contains(&(h.episode, h.step)),
            ServiceId::Slot => a.steps.remove(&(h.episode, h.step)),
            ServiceId::Ledger => a.legs.remove(&(h.episode, h.leg)),
            _ => true,
        }
    }
}

struct Held {
    since: Instant,
    host: String,
    msg: Delivery,
}

/// The agent host's gate on the up direction.
pub struct Gate {
    tag: u64,
    remote: BTreeSet<usize>,
    /// Under TLS: host → the sensors it may serve.
    may_serve: Option<BTreeMap<String, BTreeSet<usize>>>,
    claims: BTreeMap<usize, String>,
    next: BTreeMap<usize, u32>,
    held: BTreeMap<usize, BTreeMap<u32, Held>>,
    /// When each sensor's stream last moved (a message delivered or held).
    progress: BTreeMap<usize, Instant>,
    pub asked: Asked,
}

fn refusal(kind: &'static str, host: &str, sensor: Option<usize>, detail: String) -> Refusal {
    Refusal {
        kind,
        host: host.to_string(),
        sensor,
        detail,
    }
}

impl Gate {
    pub fn new(
        tag: u64,
        remote: impl IntoIterator<Item = usize>,
        may_serve: Option<BTreeMap<String, BTreeSet<usize>>>,
    ) -> Self {
        Self {
            tag,
            remote: remote.into_iter().collect(),
            may_serve,
            claims: BTreeMap::new(),
            next: BTreeMap::new(),
            held: BTreeMap::new(),
            progress: BTreeMap::new(),
            asked: Asked::default(),
        }
    }

    /// The host that claimed sensor `i`.
    pub fn claimant(&self, i: usize) -> Option<&str> {
        self.claims.get(&i).map(String::as_str)
    }

    /// `host` says it serves sensor `i` (its hello or its token): the first
    /// such host claims it; another is refused.
    pub fn claim(&mut self, host: &str, i: usize) -> Result<(), Refusal> {
        if !self.remote.contains(&i) {
            return Err(refusal(
                "not-remote",
                host,
                Some(i),
                format!("sensor {i} is not a remote sensor of this run"),
            ));
        }
        if let Some(m) = &self.may_serve
            && !m.get(host).is_some_and(|s| s.contains(&i))
        {
            return Err(refusal(
                "not-allowed",
                host,
                Some(i),
                format!("host `{host}` may not serve sensor {i} (hosts.json)"),
            ));
        }
        match self.claims.get(&i) {
            Some(h) if h == host => Ok(()),
            Some(h) => Err(refusal(
                "duplicate-host",
                host,
                Some(i),
                format!("sensor {i} is already served by host `{h}`"),
            )),
            None => {
                self.claims.insert(i, host.to_string());
                Ok(())
            }
        }
    }

    /// Admit one decoded message from `host`: what to deliver now (it and
    /// any held ones it releases, in sequence order) and what was refused.
    pub fn admit(
        &mut self,
        host: &str,
        msg: Delivery,
        now: Instant,
    ) -> (Vec<Delivery>, Vec<Refusal>) {
        let h = *msg.1.header();
        let i = h.sender as usize;
        let refuse = |kind, detail| (Vec::new(), vec![refusal(kind, host, Some(i), detail)]);
        if h.run != self.tag {
            return refuse(
                "wrong-run",
                format!("{:?} with run tag {:#x}", msg.0, h.run),
            );
        }
        if msg.0 == ServiceId::Hello {
            if let Err(r) = self.claim(host, i) {
                return (Vec::new(), vec![r]);
            }
        } else if !self.remote.contains(&i) {
            return refuse(
                "not-remote",
                format!("{:?} as sensor {i}, not a remote sensor of this run", msg.0),
            );
        } else if self.claimant(i) != Some(host) {
            return refuse(
                "not-claimant",
                format!(
                    "{:?} for sensor {i}, served by {}",
                    msg.0,
                    self.claimant(i)
                        .map_or("no host yet".into(), |c| format!("`{c}`"))
                ),
            );
        }
        let next = *self.next.entry(i).or_insert(1);
        if h.seq < next {
            return refuse(
                "replayed",
                format!("{:?} seq {} (next expected {next})", msg.0, h.seq),
            );
        }
        let held = self.held.entry(i).or_default();
        if held.contains_key(&h.seq) {
            return refuse("replayed", format!("{:?} seq {} twice", msg.0, h.seq));
        }
        if held.len() >= MAX_HELD {
            return refuse(
                "gap",
                format!("{} messages held waiting for seq {next}", held.len()),
            );
        }
        if h.seq == next {
            self.progress.insert(i, now);
        }
        held.insert(
            h.seq,
            Held {
                since: now,
                host: host.to_string(),
                msg,
            },
        );
        self.release(i)
    }

    /// Deliver sensor `i`'s held messages from its next sequence number on.
    fn release(&mut self, i: usize) -> (Vec<Delivery>, Vec<Refusal>) {
        let (mut out, mut refused) = (Vec::new(), Vec::new());
        let Some(held) = self.held.get_mut(&i) else {
            return (out, refused);
        };
        let next = self.next.entry(i).or_insert(1);
        while let Some(m) = held.remove(next) {
            *next = next.wrapping_add(1);
            let (s, r, _) = &m.msg;
            if self.asked.answers(i, *s, r.header()) {
                out.push(m.msg);
            } else {
                let h = r.header();
                refused.push(refusal(
                    "not-asked",
                    &m.host,
                    Some(i),
                    format!(
                        "{s:?} for episode {} leg {} step {}: not asked of sensor {i}",
                        h.episode, h.leg, h.step
                    ),
                ));
            }
        }
        (out, refused)
    }

    /// Sensors whose stream stood still for [`GAP_WAIT`] with a message
    /// held that long: the missing ones are lost (refused as a gap), the
    /// held ones delivered from the first.
    pub fn overdue(&mut self, now: Instant) -> (Vec<Delivery>, Vec<Refusal>) {
        let (mut out, mut refused) = (Vec::new(), Vec::new());
        let still = |i: &usize| {
            self.progress
                .get(i)
                .is_none_or(|t| now.duration_since(*t) >= GAP_WAIT)
        };
        let late: Vec<usize> = self
            .held
            .iter()
            .filter(|(i, h)| {
                still(i) && h.values().any(|m| now.duration_since(m.since) >= GAP_WAIT)
            })
            .map(|(&i, _)| i)
            .collect();
        for i in late {
            let Some(first) = self.held.get(&i).and_then(|h| h.keys().next().copied()) else {
                continue;
            };
            let next = self.next.entry(i).or_insert(1);
            refused.push(refusal(
                "gap",
                self.claims.get(&i).map_or("?", String::as_str),
                Some(i),
                format!("seq {next}..{first} never arrived"),
            ));
            *next = first;
            self.progress.insert(i, now);
            let (o, r) = self.release(i);
            out.extend(o);
            refused.extend(r);
        }
        (out, refused)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::{sensor_to_agent, to_coordinator};

    const TAG: u64 = 77;

    fn header(sender: u32, seq: u32, episode: u64, leg: u32, step: u32) -> Header {
        Header {
            run: TAG,
            episode,
            step,
            leg,
            sender,
            seq,
        }
    }
    fn hello(sender: u32) -> Delivery {
        let m = to_coordinator::Hello {
            header: header(sender, 1, 0, 0, 0),
            pid: 1,
            _pad: 0,
        };
        (ServiceId::Hello, Recorded::Hello(m), 0)
    }
    fn slot(sender: u32, seq: u32, step: u32) -> Delivery {
        let m = sensor_to_agent::Slot {
            header: header(sender, seq, 0, 0, step),
            transmitted: 0,
            _pad: 0,
            prior_digest: 0,
        };
        (ServiceId::Slot, Recorded::Slot(m), 0)
    }
    fn ask(g: &Gate, i: usize, step: u32) {
        g.asked.note(ServiceId::Truth(i), &header(0, 0, 0, 0, step));
    }

    #[test]
    fn the_first_host_claims_a_sensor_and_a_second_is_refused() {
        let mut g = Gate::new(TAG, [0, 1], None);
        let t = Instant::now();
        let (d, r) = g.admit("a", hello(0), t);
        assert_eq!((d.len(), r.len()), (1, 0));
        let (d, r) = g.admit("b", hello(0), t);
        assert!(d.is_empty());
        assert_eq!(r[0].kind, "duplicate-host");
        // A local sensor (2) cannot be spoken for.
        let (_, r) = g.admit("a", hello(2), t);
        assert_eq!(r[0].kind, "not-remote");
        // Another host's sensor cannot be spoken for either.
        ask(&g, 0, 1);
        let (_, r) = g.admit("b", slot(0, 2, 1), t);
        assert_eq!(r[0].kind, "not-claimant");
    }

    #[test]
    fn early_messages_wait_for_their_predecessor_and_replays_are_refused() {
        let mut g = Gate::new(TAG, [0], None);
        let t = Instant::now();
        g.admit("a", hello(0), t);
        ask(&g, 0, 1);
        ask(&g, 0, 2);
        let (d, r) = g.admit("a", slot(0, 3, 2), t);
        assert!(d.is_empty() && r.is_empty(), "held");
        let (d, r) = g.admit("a", slot(0, 2, 1), t);
        assert!(r.is_empty());
        let steps: Vec<u32> = d.iter().map(|m| m.1.header().step).collect();
        assert_eq!(steps, [1, 2]);
        let (_, r) = g.admit("a", slot(0, 2, 1), t);
        assert_eq!(r[0].kind, "replayed");
    }

    #[test]
    fn an_answer_nobody_asked_for_is_refused_and_a_gap_ends() {
        let mut g = Gate::new(TAG, [0], None);
        let t = Instant::now();
        g.admit("a", hello(0), t);
        let (d, r) = g.admit("a", slot(0, 2, 9), t);
        assert!(d.is_empty());
        assert_eq!(r[0].kind, "not-asked");
        let other = Header {
            run: TAG + 1,
            ..header(0, 3, 0, 0, 1)
        };
        let (_, r) = g.admit(
            "a",
            (
                ServiceId::Slot,
                Recorded::Slot(sensor_to_agent::Slot {
                    header: other,
                    transmitted: 0,
                    _pad: 0,
                    prior_digest: 0,
                }),
                0,
            ),
            t,
        );
        assert_eq!(r[0].kind, "wrong-run");
        ask(&g, 0, 5);
        let (d, _) = g.admit("a", slot(0, 5, 5), t);
        assert!(d.is_empty(), "held behind seq 3 and 4");
        let (d, r) = g.overdue(t + GAP_WAIT);
        assert_eq!((d.len(), r[0].kind), (1, "gap"));
    }
}
