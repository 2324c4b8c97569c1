//! The agent host's bound on every wait of a remote run: what the run asked
//! of each remote sensor and has not had answered yet, and how long that may
//! last before the sensor is a named dead link.
//!
//! A remote sensor is asked two things over the link, and answers each
//! (`sensor-node`): a `truth` (the agent opened its slot of episode e, step
//! k) is answered by its `slot` of (e, k); a closing `threshold` (the
//! coordinator closed its leg (e, l)) by its `ledger` of (e, l). While a
//! question is open the agent or the coordinator waits for the answer, so a
//! question older than [`Bound::wait`] is a wait the link made silent: the
//! message went missing (or its sensor stalled) and the agent host cuts the
//! sensor (docs/MODEL.md, runtime: "No silent wait on the link").
//!
//! The bound is derived from the link: at least [`FLOOR`], ten link leases,
//! and ten times the slowest answer seen so far in the run (a link that is
//! slow all along gets the room it showed it needs).
//!
//! Pure: no clock, no Zenoh; the bridge passes the instants in.

use etp_runtime::recording::Recorded;
use etp_runtime::wire::{Header, ServiceId, ThresholdKind};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// The least time an open question may wait before its sensor is cut. It
/// equals Zenoh's wait for a peer that stopped reading
/// ([`crate::session::STALLED_PEER_CLOSE`]): a slower answer is no answer.
pub const FLOOR: Duration = Duration::from_secs(5);

/// How many leases, and how many of the slowest answer seen, the bound is at
/// least.
pub const LEASES: u32 = 10;
pub const SLOWEST: u32 = 10;

/// What the run asked a remote sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Question {
    /// Its slot of (episode, leg, step): asked by the agent's `truth`.
    Slot { episode: u64, leg: u32, step: u32 },
    /// Its ledger of (episode, leg): asked by the coordinator's closing
    /// `threshold`.
    Ledger { episode: u64, leg: u32 },
}

impl std::fmt::Display for Question {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::Slot { episode, leg, step } => {
                write!(f, "slot of episode {episode} leg {leg} step {step}")
            }
            Self::Ledger { episode, leg } => write!(f, "ledger of episode {episode} leg {leg}"),
        }
    }
}

impl Question {
    /// The question a downlink message asks, if any (`kind`: a threshold's
    /// kind, read from its payload by the caller).
    pub fn of_downlink(s: ServiceId, h: &Header, threshold_kind: Option<u32>) -> Option<Self> {
        match s {
            ServiceId::Truth(_) => Some(Self::Slot {
                episode: h.episode,
                leg: h.leg,
                step: h.step,
            }),
            ServiceId::Threshold(_)
                if threshold_kind
                    .and_then(|k| ThresholdKind::try_from(k).ok())
                    .is_some_and(|k| k == ThresholdKind::Close) =>
            {
                Some(Self::Ledger {
                    episode: h.episode,
                    leg: h.leg,
                })
            }
            _ => None,
        }
    }

    /// The answer that closes this question.
    fn answer(&self) -> Answer {
        match *self {
            Self::Slot { episode, step, .. } => Answer::Slot { episode, step },
            Self::Ledger { episode, leg } => Answer::Ledger { episode, leg },
        }
    }
}

/// What a sensor's message answers: a slot of (episode, step), a ledger of
/// (episode, leg).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Answer {
    Slot { episode: u64, step: u32 },
    Ledger { episode: u64, leg: u32 },
}

impl Answer {
    fn of(m: &Recorded) -> Option<Self> {
        let h = m.header();
        match m {
            Recorded::Slot(_) => Some(Self::Slot {
                episode: h.episode,
                step: h.step,
            }),
            Recorded::Ledger(_) => Some(Self::Ledger {
                episode: h.episode,
                leg: h.leg,
            }),
            _ => None,
        }
    }
}

/// Answers remembered per sensor that came before their question was
/// noted: the outbound thread notes a question after its put returns, and
/// on a fast link the answer can reach the agent host's loop first.
const EARLY: usize = 64;

/// How long an open question may wait.
#[derive(Debug, Clone, Copy)]
pub struct Bound {
    lease: Duration,
    slowest: Duration,
}

impl Bound {
    pub fn new(lease: Duration) -> Self {
        Self {
            lease,
            slowest: Duration::ZERO,
        }
    }

    /// The bound now: max([`FLOOR`], [`LEASES`] × lease, [`SLOWEST`] ×
    /// slowest answer so far).
    pub fn wait(&self) -> Duration {
        FLOOR.max(self.lease * LEASES).max(self.slowest * SLOWEST)
    }

    /// The slowest answer seen so far.
    pub fn slowest(&self) -> Duration {
        self.slowest
    }
}

/// An open question that waited past the bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Overdue {
    pub sensor: usize,
    pub question: Question,
    /// How long it has waited.
    pub waited: Duration,
}

/// The open questions of every remote sensor, oldest first.
#[derive(Debug)]
pub struct Questions {
    open: BTreeMap<usize, Vec<(Question, Instant)>>,
    /// Per sensor, the last [`EARLY`] answers that matched no open question.
    early: BTreeMap<usize, std::collections::VecDeque<Answer>>,
    bound: Bound,
}

impl Questions {
    pub fn new(lease: Duration) -> Self {
        Self {
            open: BTreeMap::new(),
            early: BTreeMap::new(),
            bound: Bound::new(lease),
        }
    }

    /// `sensor` was asked `q` at `at`.
    pub fn asked(&mut self, sensor: usize, q: Question, at: Instant) {
        if let Some(e) = self.early.get_mut(&sensor)
            && let Some(i) = e.iter().position(|a| *a == q.answer())
        {
            e.remove(i);
            return;
        }
        let v = self.open.entry(sensor).or_default();
        if !v.iter().any(|(o, _)| *o == q) {
            v.push((q, at));
        }
    }

    /// A message of `sensor` reached the agent host at `at`: the question it
    /// answers is closed (the time it took feeds the bound).
    pub fn delivered(&mut self, sensor: usize, m: &Recorded, at: Instant) {
        let Some(a) = Answer::of(m) else {
            return;
        };
        let v = self.open.entry(sensor).or_default();
        if let Some(i) = v.iter().position(|(q, _)| q.answer() == a) {
            let (_, asked) = v.remove(i);
            self.bound.slowest = self.bound.slowest.max(at.saturating_duration_since(asked));
        } else {
            let e = self.early.entry(sensor).or_default();
            if e.len() == EARLY {
                e.pop_front();
            }
            e.push_back(a);
        }
    }

    /// The sensor is no longer waited for (cut, or lost): its questions go.
    pub fn forget(&mut self, sensor: usize) {
        self.open.remove(&sensor);
        self.early.remove(&sensor);
    }

    /// The oldest question past the bound at `now`, if any.
    pub fn overdue(&self, now: Instant) -> Option<Overdue> {
        let bound = self.bound.wait();
        self.open
            .iter()
            .flat_map(|(&sensor, v)| v.iter().map(move |&(q, at)| (sensor, q, at)))
            .map(|(sensor, question, at)| Overdue {
                sensor,
                question,
                waited: now.saturating_duration_since(at),
            })
            .filter(|o| o.waited >= bound)
            .max_by_key(|o| o.waited)
    }

    pub fn bound(&self) -> Bound {
        self.bound
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::Message;
    use etp_runtime::wire::messages::sensor_to_agent as s2a;
    use etp_runtime::wire::messages::sensor_to_coordinator as s2c;

    fn header(episode: u64, leg: u32, step: u32) -> Header {
        Header {
            run: 1,
            episode,
            step,
            leg,
            sender: 2,
            seq: 0,
        }
    }

    #[test]
    fn a_truth_asks_for_its_slot_and_a_closing_threshold_for_its_ledger() {
        let h = header(13, 1, 87);
        assert_eq!(
            Question::of_downlink(ServiceId::Truth(2), &h, None),
            Some(Question::Slot {
                episode: 13,
                leg: 1,
                step: 87
            })
        );
        let close = ThresholdKind::Close.code();
        let open = ThresholdKind::Open.code();
        assert_eq!(
            Question::of_downlink(ServiceId::Threshold(2), &h, Some(close)),
            Some(Question::Ledger {
                episode: 13,
                leg: 1
            })
        );
        assert_eq!(
            Question::of_downlink(ServiceId::Threshold(2), &h, Some(open)),
            None
        );
        assert_eq!(Question::of_downlink(ServiceId::Ack(2), &h, None), None);
        assert_eq!(
            Question::Slot {
                episode: 13,
                leg: 1,
                step: 87
            }
            .to_string(),
            "slot of episode 13 leg 1 step 87"
        );
    }

    #[test]
    fn an_unanswered_question_is_overdue_after_the_bound_and_an_answered_one_never() {
        let t0 = Instant::now();
        let lease = Duration::from_millis(300);
        let mut q = Questions::new(lease);
        assert_eq!(q.bound().wait(), FLOOR, "10 leases are less than the floor");
        let slot = Question::Slot {
            episode: 13,
            leg: 1,
            step: 87,
        };
        q.asked(1, slot, t0);
        q.asked(
            2,
            Question::Ledger {
                episode: 13,
                leg: 0,
            },
            t0,
        );
        // The ledger comes; the slot never does.
        let ledger = s2c::Ledger {
            header: header(13, 0, 0),
            ..Default::default()
        }
        .into_recorded();
        q.delivered(2, &ledger, t0 + Duration::from_millis(40));
        // Another step's slot does not answer it.
        let other = s2a::Slot {
            header: header(13, 1, 86),
            ..Default::default()
        }
        .into_recorded();
        q.delivered(1, &other, t0 + Duration::from_millis(50));
        assert_eq!(q.overdue(t0 + FLOOR - Duration::from_millis(1)), None);
        assert_eq!(
            q.overdue(t0 + FLOOR),
            Some(Overdue {
                sensor: 1,
                question: slot,
                waited: FLOOR
            })
        );
        let answer = s2a::Slot {
            header: header(13, 1, 87),
            ..Default::default()
        }
        .into_recorded();
        q.delivered(1, &answer, t0 + FLOOR);
        assert_eq!(q.overdue(t0 + FLOOR * 100), None);
    }

    /// The race the all-remote soak found: the answer reached the agent
    /// host's loop before the outbound thread noted its question.
    #[test]
    fn an_answer_that_came_before_its_question_closes_it() {
        let t0 = Instant::now();
        let mut q = Questions::new(Duration::from_millis(300));
        let answer = s2a::Slot {
            header: header(11, 4, 255),
            ..Default::default()
        }
        .into_recorded();
        q.delivered(2, &answer, t0);
        q.asked(
            2,
            Question::Slot {
                episode: 11,
                leg: 4,
                step: 255,
            },
            t0,
        );
        assert_eq!(q.overdue(t0 + FLOOR * 10), None);
    }

    #[test]
    fn the_bound_grows_with_the_lease_and_with_the_slowest_answer() {
        let t0 = Instant::now();
        let mut q = Questions::new(Duration::from_secs(1));
        assert_eq!(q.bound().wait(), Duration::from_secs(10));
        let s = Question::Slot {
            episode: 0,
            leg: 0,
            step: 1,
        };
        q.asked(0, s, t0);
        let answer = s2a::Slot {
            header: header(0, 0, 1),
            ..Default::default()
        }
        .into_recorded();
        q.delivered(0, &answer, t0 + Duration::from_millis(1500));
        assert_eq!(q.bound().slowest(), Duration::from_millis(1500));
        assert_eq!(q.bound().wait(), Duration::from_secs(15));
    }
}
