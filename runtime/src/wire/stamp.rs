//! The sender's time of every message.
//!
//! Every publish-subscribe service carries an iceoryx2 user header,
//! [`PublishTime`]: the time its sender published the sample, in ns since
//! the Unix epoch (`CLOCK_REALTIME` of the sender's host). It is written in
//! one place, [`super::Pub::publish`], which every publisher of a run goes
//! through; the recorder writes it as the message's MCAP `publish_time`
//! (its `log_time` stays the recorder's receive time).
//!
//! It is not in the payload: the payload's `Header` and every format's
//! schema stay as they are, and no result of the maths can depend on it.
//! Across hosts the Zenoh bridge carries it in front of the payload
//! ([`link_frame`]) and publishes the remote sample with the remote sender's
//! time ([`super::Pub::publish_at`]): a time from another host's clock,
//! which may differ from this one's. It is only ever recorded, never used
//! to order anything (a recording is ordered by `log_time`), so a forged or
//! garbage time is just a number in the file.

use std::time::{SystemTime, UNIX_EPOCH};

/// The user header of every publish-subscribe service: when the sender
/// published the sample (ns since the Unix epoch, the sender's clock).
pub type PublishTime = u64;

/// Now, in ns since the Unix epoch (`CLOCK_REALTIME`); 0 for a clock set
/// before 1970, `u64::MAX` past the year 2554.
pub fn now_ns() -> PublishTime {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// Version of what the Zenoh bridge puts on the link, checked when a
/// sensor host joins (both ways: the run's description names the agent
/// host's, a claim names the sensor host's), so a peer of another version
/// is refused by name instead of its messages being misread. 1: the
/// payload alone (bincode, as format-4 recordings held it); 2: the
/// sender's [`PublishTime`] in front of it ([`link_frame`]).
pub const LINK_PROTOCOL: u32 = 2;

/// Bytes of the [`PublishTime`] in front of each payload on the link.
pub const LINK_TIME_BYTES: usize = 8;

/// One message on the link: its sender's time (little-endian `u64`), then
/// the payload.
pub fn link_frame(time: PublishTime, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(LINK_TIME_BYTES + payload.len());
    out.extend_from_slice(&time.to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// A message of the link split into its sender's time and its payload;
/// `None` when it is too short to hold a time. Any time is accepted: it
/// is only recorded.
pub fn link_unframe(bytes: &[u8]) -> Option<(PublishTime, &[u8])> {
    let (time, payload) = bytes.split_first_chunk::<LINK_TIME_BYTES>()?;
    Some((u64::from_le_bytes(*time), payload))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_the_time_then_the_payload_and_any_time_reads_back() {
        for time in [0, 1, now_ns(), u64::MAX] {
            let f = link_frame(time, &[7, 8, 9]);
            assert_eq!(f.len(), LINK_TIME_BYTES + 3);
            assert_eq!(link_unframe(&f), Some((time, &[7u8, 8, 9][..])));
        }
        assert_eq!(link_unframe(&[1, 2, 3]), None);
        assert_eq!(link_unframe(&[0; 8]), Some((0, &[][..])));
    }

    #[test]
    fn now_is_after_2020() {
        assert!(now_ns() > 1_577_836_800_000_000_000);
    }
}
