//! The feed of the live view (`etp run --live`): what the agent tells the
//! view, and the agent's end of it ([`LiveTap`]).
//!
//! The view must never slow or change the run, so the feed is a Unix
//! datagram socket in the run's private folder, written **non-blocking**:
//! a datagram the view has no room for is dropped (counted), never waited
//! for, and no error of the feed ever reaches the run. The agent sends a
//! [`LiveMsg::Slot`] at most every [`FRAME_EVERY`] (it looks at the clock
//! only every [`CLOCK_EVERY`] slots) and one [`LiveMsg::Outcome`] per
//! episode; every message carries the run's running [`Totals`], so a
//! dropped frame loses a picture, never a count. Nothing here touches a
//! service of the run: the iceoryx2 traffic, and therefore every count and
//! bit of the run, is the same with and without a view.

use serde::{Deserialize, Serialize};
use std::io;
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::time::{Duration, Instant};

/// The shortest interval between two slot frames (50 frames/s at most).
pub const FRAME_EVERY: Duration = Duration::from_millis(20);
/// The agent reads the clock once every this many slots.
pub const CLOCK_EVERY: u32 = 32;
/// The largest datagram the view reads (a frame of n = 6 with 32 sensors
/// is about 2 KiB).
pub const MAX_DATAGRAM: usize = 64 * 1024;

/// The run so far, as the agent counts it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Totals {
    /// Episodes finished, and by outcome.
    pub episodes: u64,
    pub target: u64,
    pub collision: u64,
    pub free: u64,
    /// Plant steps (slots) so far, every episode.
    pub steps: u64,
    /// Per sensor: slots served, transmission attempts (each costs the
    /// sensor's c_m: the energy), measurements delivered.
    pub slots: Vec<u64>,
    pub attempts: Vec<u64>,
    pub delivered: Vec<u64>,
    /// Attempts in finished episodes only (what the predicted energy per
    /// episode compares to).
    pub attempts_finished: Vec<u64>,
    /// Every flag of the channel monitor so far (at most three per
    /// sensor), so a dropped frame loses none.
    pub drift: Vec<crate::report::DriftRecord>,
}

/// One slot as the agent saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlotFrame {
    pub episode: u64,
    pub leg: u32,
    pub step: u32,
    /// The serving sensor (index in the scenario) and the leg's δ.
    pub sensor: u32,
    pub delta: f64,
    /// The true state, and the prior the serving sensor triggered on
    /// (mean, covariance row-major n × n).
    pub x: Vec<f64>,
    pub mean: Vec<f64>,
    pub cov: Vec<f64>,
    /// Transmission attempts of the serving sensor in this slot, and whether
    /// a measurement was delivered.
    pub attempts: u32,
    pub delivered: bool,
    pub totals: Totals,
}

/// An episode's end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutcomeFrame {
    pub episode: u64,
    /// `wire::OutcomeCode` as its code.
    pub outcome: u32,
    pub steps: u32,
    pub degraded: bool,
    pub totals: Totals,
}

/// What crosses the feed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum LiveMsg {
    Slot(SlotFrame),
    Outcome(OutcomeFrame),
}

impl LiveMsg {
    pub fn encode(&self, buf: &mut Vec<u8>) -> Result<(), bincode::error::EncodeError> {
        buf.clear();
        bincode::serde::encode_into_std_write(self, buf, bincode::config::standard()).map(|_| ())
    }
    pub fn decode(bytes: &[u8]) -> Result<Self, bincode::error::DecodeError> {
        bincode::serde::decode_from_slice(bytes, bincode::config::standard()).map(|(m, _)| m)
    }
}

/// The agent's end of the feed: counts every slot, sends a frame when one
/// is due, never blocks and never fails the run.
#[derive(Debug)]
pub struct LiveTap {
    socket: UnixDatagram,
    totals: Totals,
    /// Attempts of the episode in progress, per sensor.
    episode_attempts: Vec<u64>,
    until_clock: u32,
    last_frame: Option<Instant>,
    buf: Vec<u8>,
    /// Frames sent, and frames dropped (the view had no room, or is gone).
    pub sent: u64,
    pub dropped: u64,
}

impl LiveTap {
    /// Connect to the view's socket at `path` (made by `etp run --live`).
    pub fn connect(path: &Path, sensors: usize) -> io::Result<Self> {
        let socket = UnixDatagram::unbound()?;
        socket.connect(path)?;
        socket.set_nonblocking(true)?;
        Ok(Self {
            socket,
            totals: Totals {
                slots: vec![0; sensors],
                attempts: vec![0; sensors],
                delivered: vec![0; sensors],
                attempts_finished: vec![0; sensors],
                ..Totals::default()
            },
            episode_attempts: vec![0; sensors],
            until_clock: 0,
            last_frame: None,
            buf: Vec::with_capacity(4096),
            sent: 0,
            dropped: 0,
        })
    }

    /// Count one closed slot of `sensor`; `true` if a frame is due (then
    /// call [`Self::send_slot`]).
    pub fn count_slot(&mut self, sensor: usize, attempts: u32, delivered: bool) -> bool {
        self.totals.steps += 1;
        if let (Some(s), Some(a), Some(d), Some(e)) = (
            self.totals.slots.get_mut(sensor),
            self.totals.attempts.get_mut(sensor),
            self.totals.delivered.get_mut(sensor),
            self.episode_attempts.get_mut(sensor),
        ) {
            *s += 1;
            *a += u64::from(attempts);
            *d += u64::from(delivered);
            *e += u64::from(attempts);
        }
        if self.until_clock > 0 {
            self.until_clock -= 1;
            return false;
        }
        self.until_clock = CLOCK_EVERY - 1;
        let now = Instant::now();
        match self.last_frame {
            Some(t) if now.duration_since(t) < FRAME_EVERY => false,
            _ => {
                self.last_frame = Some(now);
                true
            }
        }
    }

    /// A flag of the channel monitor: every later frame carries it (the
    /// view shows each flag once).
    pub fn note_drift(&mut self, flag: crate::report::DriftRecord) {
        self.totals.drift.push(flag);
    }

    /// The running totals.
    pub fn totals(&self) -> &Totals {
        &self.totals
    }

    /// Send a slot frame (its `totals` are replaced by the tap's).
    pub fn send_slot(&mut self, mut frame: SlotFrame) {
        frame.totals = self.totals.clone();
        self.send(&LiveMsg::Slot(frame));
    }

    /// Count an episode's end and send it (`outcome` a `wire::OutcomeCode`).
    pub fn send_outcome(&mut self, episode: u64, outcome: u32, steps: u32, degraded: bool) {
        use crate::wire::OutcomeCode;
        let t = &mut self.totals;
        t.episodes += 1;
        match OutcomeCode::try_from(outcome) {
            Ok(OutcomeCode::Target) => t.target += 1,
            Ok(OutcomeCode::Collision) => t.collision += 1,
            Ok(OutcomeCode::Free) => t.free += 1,
            _ => {}
        }
        for (f, e) in t
            .attempts_finished
            .iter_mut()
            .zip(self.episode_attempts.iter_mut())
        {
            *f += *e;
            *e = 0;
        }
        let frame = OutcomeFrame {
            episode,
            outcome,
            steps,
            degraded,
            totals: self.totals.clone(),
        };
        self.send(&LiveMsg::Outcome(frame));
    }

    fn send(&mut self, m: &LiveMsg) {
        if m.encode(&mut self.buf).is_err() {
            self.dropped += 1;
            return;
        }
        // Non-blocking: a full queue (WouldBlock), a view that is gone
        // (ConnectionRefused) or anything else drops this frame only.
        match self.socket.send(&self.buf) {
            Ok(_) => self.sent += 1,
            Err(_) => self.dropped += 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> SlotFrame {
        SlotFrame {
            episode: 3,
            leg: 1,
            step: 40,
            sensor: 1,
            delta: 1.5,
            x: vec![1.0, 2.0],
            mean: vec![1.1, 1.9],
            cov: vec![0.2, 0.01, 0.01, 0.3],
            attempts: 1,
            delivered: true,
            totals: Totals::default(),
        }
    }

    /// The agent's cost of the view (`cargo test --release -p etp-runtime
    /// live::tests::tap_cost -- --ignored --nocapture`): a slot counted, a
    /// frame due every 20 ms sent (encoded, non-blocking send); a slot of a
    /// run takes ~50 µs. Asserts only the rate limit.
    #[test]
    #[ignore = "a measurement: run by hand"]
    fn tap_cost() -> Result<(), Box<dyn std::error::Error>> {
        let dir = std::env::temp_dir().join(format!("etp-live-cost-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let path = dir.join("feed");
        let _ = std::fs::remove_file(&path);
        let view = UnixDatagram::bind(&path)?;
        view.set_nonblocking(true)?;
        let mut tap = LiveTap::connect(&path, 7)?;
        let slots = 5_000_000u32;
        let start = Instant::now();
        for k in 0..slots {
            if tap.count_slot((k % 7) as usize, k % 4 / 3, k % 4 == 3) {
                tap.send_slot(frame());
                // The view reads: the queue never fills.
                let mut buf = vec![0u8; MAX_DATAGRAM];
                while view.recv(&mut buf).is_ok() {}
            }
        }
        let elapsed = start.elapsed();
        let ns = elapsed.as_nanos() as f64 / f64::from(slots);
        eprintln!(
            "{slots} slots in {elapsed:?}: {ns:.1} ns per slot, {} frames sent, {} dropped",
            tap.sent, tap.dropped
        );
        let most = elapsed.as_millis() / FRAME_EVERY.as_millis() + 1;
        assert!(u128::from(tap.sent) <= most, "{} frames > {most}", tap.sent);
        // One frame: encoded and sent (the view drains every 8, as a
        // reader that keeps up).
        let frames = 20_000u32;
        let mut buf = vec![0u8; MAX_DATAGRAM];
        let start = Instant::now();
        for k in 0..frames {
            tap.send_slot(frame());
            if k % 8 == 7 {
                while view.recv(&mut buf).is_ok() {}
            }
        }
        let per_frame = start.elapsed().as_nanos() as f64 / f64::from(frames) / 1e3;
        eprintln!(
            "{per_frame:.2} µs per frame (sent and read), {} dropped",
            tap.dropped
        );
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }

    #[test]
    fn a_message_round_trips() -> Result<(), Box<dyn std::error::Error>> {
        let m = LiveMsg::Slot(frame());
        let mut buf = Vec::new();
        m.encode(&mut buf)?;
        assert!(buf.len() < MAX_DATAGRAM);
        assert_eq!(LiveMsg::decode(&buf)?, m);
        Ok(())
    }

    #[test]
    fn frames_are_rate_limited_and_counts_are_not() -> Result<(), Box<dyn std::error::Error>> {
        let dir = std::env::temp_dir().join(format!("etp-live-tap-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let path = dir.join("feed");
        let _ = std::fs::remove_file(&path);
        let view = UnixDatagram::bind(&path)?;
        let mut tap = LiveTap::connect(&path, 2)?;
        // The first slot is due; the next CLOCK_EVERY − 1 are not even looked at.
        assert!(tap.count_slot(0, 1, true));
        tap.send_slot(frame());
        let due = (0..CLOCK_EVERY - 1)
            .filter(|_| tap.count_slot(1, 0, false))
            .count();
        assert_eq!(due, 0);
        tap.send_outcome(3, crate::wire::OutcomeCode::Target.code(), 32, false);
        let mut buf = vec![0u8; MAX_DATAGRAM];
        let n = view.recv(&mut buf)?;
        let LiveMsg::Slot(f) = LiveMsg::decode(&buf[..n])? else {
            panic!("a slot frame first");
        };
        assert_eq!(f.totals.attempts, vec![1, 0]);
        let n = view.recv(&mut buf)?;
        let LiveMsg::Outcome(o) = LiveMsg::decode(&buf[..n])? else {
            panic!("then the outcome");
        };
        assert_eq!(o.totals.steps, u64::from(CLOCK_EVERY));
        assert_eq!(o.totals.slots, vec![1, u64::from(CLOCK_EVERY - 1)]);
        assert_eq!(o.totals.attempts_finished, vec![1, 0]);
        assert_eq!((o.totals.episodes, o.totals.target), (1, 1));
        // The view gone: frames drop, the tap goes on.
        drop(view);
        tap.send_outcome(4, crate::wire::OutcomeCode::Free.code(), 1, false);
        assert_eq!((tap.sent, tap.dropped), (2, 1));
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }
}
