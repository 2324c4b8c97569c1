//! The MCAP recording format of a run (DESIGN.md "Recording"): the one place
//! that names channels and schemas, encodes and decodes payloads, and reads a
//! recording leniently (an unfinished file from a crashed recorder too).
//!
//! * One channel per publish-subscribe service; its topic is the service name
//!   without the `etp/<run-id>/` prefix (`measurement`, `sensor/0/truth`, …).
//! * Message encoding [`MESSAGE_ENCODING`]: bincode 2.0.1 through serde with
//!   `config::legacy()` (fixed-width little-endian integers, so any reader can
//!   `struct.unpack` a payload: the field order is that of the `#[repr(C)]`
//!   struct, padding fields included).
//! * Schema encoding [`SCHEMA_ENCODING`]: the schema data is a text listing of
//!   the fields (`name: type`), named after the iceoryx2 type name.
//! * Metadata records: [`META_RUN`] (format version, software version, run
//!   id, seed, episodes, scenario name, scenario content hash
//!   [`META_RUN_SCENARIO_HASH`]), [`META_SCENARIO`] (`toml`),
//!   [`META_STRATEGY`] (`json`), [`META_PREDICTION`] (`json`: what the
//!   strategy predicts, for "energy vs prediction").
//! * `log_time`/`publish_time`: ns since the Unix epoch when the recorder took
//!   the sample; `sequence`: per-channel count.

use crate::wire::{
    ServiceId, agent_to_coordinator as a2c, agent_to_sensor as a2s, coordinator_to_agent as c2a,
    coordinator_to_all as c2all, sensor_to_agent as s2a, sensor_to_coordinator as s2c,
    to_coordinator as tc,
};

mod integrity;
mod read;
mod verify;

pub use integrity::{META_RUN_SCENARIO_HASH, check_metadata};
pub use read::{Contents, RawMessage, read_lenient};
pub use verify::{Mismatch, VerifyReport, verify};

/// Version of this format (metadata `etp.run` / `format_version`).
pub const FORMAT_VERSION: &str = "1";
/// MCAP profile string.
pub const PROFILE: &str = "etpareto";
/// Message encoding of every channel.
pub const MESSAGE_ENCODING: &str = "bincode2-serde-legacy";
/// Schema encoding of every schema.
pub const SCHEMA_ENCODING: &str = "etp-field-list";
/// Metadata record names.
pub const META_RUN: &str = "etp.run";
pub const META_SCENARIO: &str = "etp.scenario";
pub const META_STRATEGY: &str = "etp.strategy";
pub const META_PREDICTION: &str = "etp.prediction";

/// Why a recording could not be encoded, decoded or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("unknown channel topic `{0}`")]
    UnknownTopic(String),
    #[error("channel `{topic}`: payload does not decode: {reason}")]
    Decode { topic: String, reason: String },
    #[error("encoding a payload: {0}")]
    Encode(String),
    #[error("recording metadata: {0}")]
    Metadata(String),
    #[error("{0}: not an MCAP recording: {1}")]
    NotMcap(String, String),
}

const HEADER_FIELDS: &str = "header.run: u64\nheader.episode: u64\nheader.step: u32\nheader.leg: u32\nheader.sender: u32\nheader.seq: u32\n";

/// The kind of message a channel carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    Control,
    Threshold,
    Truth,
    Prior,
    Measurement,
    Slot,
    Waypoint,
    Outcome,
    Ledger,
    Hello,
}

impl Kind {
    /// The schema name (the iceoryx2 type name).
    pub fn schema_name(self) -> &'static str {
        match self {
            Self::Control => "etp::Control",
            Self::Threshold => "etp::Threshold",
            Self::Truth => "etp::Truth",
            Self::Prior => "etp::Prior",
            Self::Measurement => "etp::Measurement",
            Self::Slot => "etp::Slot",
            Self::Waypoint => "etp::Waypoint",
            Self::Outcome => "etp::Outcome",
            Self::Ledger => "etp::Ledger",
            Self::Hello => "etp::Hello",
        }
    }

    /// The schema data: the fields after the header, in wire order.
    pub fn schema_text(self) -> String {
        let tail = match self {
            Self::Control => {
                "kind: u32\ndim: u32\nseed: u64\ninitial_mean: [f64; 6]\ninitial_cov: [[f64; 6]; 6]\n"
            }
            Self::Threshold => "kind: u32\nsensor: u32\ndelta_index: u32\n_pad: u32\ndelta: f64\n",
            Self::Truth => "dim: u32\n_pad: u32\nx: [f64; 6]\n",
            Self::Prior => "dim: u32\n_pad: u32\nmean: [f64; 6]\ncov: [[f64; 6]; 6]\n",
            Self::Measurement => "dim: u32\nsequence: u32\ny: [f64; 6]\n",
            Self::Slot => "transmitted: u32\n_pad: u32\n",
            Self::Waypoint => {
                "dim: u32\nprev_steps: u32\nprev_received: u32\nprev_degraded: u32\nmean: [f64; 6]\ncov: [[f64; 6]; 6]\n"
            }
            Self::Outcome => {
                "outcome: u32\ndegraded: u32\nsteps: u32\nslots: u32\nreceived: u32\nlast_steps: u32\nlast_received: u32\ndead_slots: u32\ndetect_us: u64\ndetected_unix_ns: u64\nwait_started_unix_ns: u64\ndead_sensor: u32\n_pad: u32\n"
            }
            Self::Ledger => "slots: u32\ntransmissions: u32\nenergy: f64\n",
            Self::Hello => "pid: u32\n_pad: u32\n",
        };
        format!(
            "# {} ({MESSAGE_ENCODING})\n{HEADER_FIELDS}{tail}",
            self.schema_name()
        )
    }
}

/// The channel topic of a service (its name without `etp/<run-id>/`), and
/// the kind it carries; `None` for event services (not recorded).
pub fn channel(service: ServiceId) -> Option<(String, Kind)> {
    Some(match service {
        ServiceId::Control => ("control".into(), Kind::Control),
        ServiceId::Threshold => ("threshold".into(), Kind::Threshold),
        ServiceId::Truth(i) => (format!("sensor/{i}/truth"), Kind::Truth),
        ServiceId::Prior(i) => (format!("sensor/{i}/prior"), Kind::Prior),
        ServiceId::Measurement => ("measurement".into(), Kind::Measurement),
        ServiceId::Slot => ("slot".into(), Kind::Slot),
        ServiceId::Waypoint => ("waypoint".into(), Kind::Waypoint),
        ServiceId::Outcome => ("outcome".into(), Kind::Outcome),
        ServiceId::Ledger => ("ledger".into(), Kind::Ledger),
        ServiceId::Hello => ("hello".into(), Kind::Hello),
        ServiceId::AgentWake | ServiceId::CoordinatorWake | ServiceId::SensorWake(_) => {
            return None;
        }
    })
}

/// The service a channel topic was recorded from (the inverse of [`channel`]).
pub fn service_of_topic(topic: &str) -> Option<ServiceId> {
    let sensor = |tail: &str| -> Option<usize> {
        topic
            .strip_prefix("sensor/")?
            .strip_suffix(tail)?
            .parse()
            .ok()
    };
    Some(match topic {
        "control" => ServiceId::Control,
        "threshold" => ServiceId::Threshold,
        "measurement" => ServiceId::Measurement,
        "slot" => ServiceId::Slot,
        "waypoint" => ServiceId::Waypoint,
        "outcome" => ServiceId::Outcome,
        "ledger" => ServiceId::Ledger,
        "hello" => ServiceId::Hello,
        _ => {
            if let Some(i) = sensor("/truth") {
                ServiceId::Truth(i)
            } else {
                ServiceId::Prior(sensor("/prior")?)
            }
        }
    })
}

/// The kind of a channel topic.
pub fn kind_of_topic(topic: &str) -> Option<Kind> {
    channel(service_of_topic(topic)?).map(|(_, kind)| kind)
}

/// One decoded message.
#[derive(Debug, Clone, PartialEq)]
pub enum Recorded {
    Control(c2a::Control),
    Threshold(c2all::Threshold),
    Truth(a2s::Truth),
    Prior(a2s::Prior),
    Measurement(s2a::Measurement),
    Slot(s2a::Slot),
    Waypoint(a2c::Waypoint),
    Outcome(a2c::Outcome),
    Ledger(s2c::Ledger),
    Hello(tc::Hello),
}

fn cfg() -> bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Fixint,
    bincode::config::NoLimit,
> {
    bincode::config::legacy()
}

/// Encode one payload (THE encoder of the recording).
pub fn encode<T: serde::Serialize>(payload: &T) -> Result<Vec<u8>, RecordingError> {
    bincode::serde::encode_to_vec(payload, cfg()).map_err(|e| RecordingError::Encode(e.to_string()))
}

fn dec<T: serde::de::DeserializeOwned>(topic: &str, data: &[u8]) -> Result<T, RecordingError> {
    let err = |reason: String| RecordingError::Decode {
        topic: topic.to_string(),
        reason,
    };
    let (v, used) =
        bincode::serde::decode_from_slice(data, cfg()).map_err(|e| err(e.to_string()))?;
    if used != data.len() {
        return Err(err(format!("{} trailing bytes", data.len() - used)));
    }
    Ok(v)
}

/// Decode one payload of a channel (THE decoder of the recording).
pub fn decode(topic: &str, data: &[u8]) -> Result<Recorded, RecordingError> {
    let kind = kind_of_topic(topic).ok_or_else(|| RecordingError::UnknownTopic(topic.into()))?;
    Ok(match kind {
        Kind::Control => Recorded::Control(dec(topic, data)?),
        Kind::Threshold => Recorded::Threshold(dec(topic, data)?),
        Kind::Truth => Recorded::Truth(dec(topic, data)?),
        Kind::Prior => Recorded::Prior(dec(topic, data)?),
        Kind::Measurement => Recorded::Measurement(dec(topic, data)?),
        Kind::Slot => Recorded::Slot(dec(topic, data)?),
        Kind::Waypoint => Recorded::Waypoint(dec(topic, data)?),
        Kind::Outcome => Recorded::Outcome(dec(topic, data)?),
        Kind::Ledger => Recorded::Ledger(dec(topic, data)?),
        Kind::Hello => Recorded::Hello(dec(topic, data)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Header;

    #[test]
    fn every_recorded_service_maps_to_a_topic_and_back() {
        for s in ServiceId::all_pubsub(12) {
            let (topic, kind) = channel(s).expect("pub-sub services are recorded");
            assert_eq!(service_of_topic(&topic), Some(s), "{topic}");
            assert_eq!(kind_of_topic(&topic), Some(kind), "{topic}");
        }
        for bad in [
            "",
            "sensor/x/truth",
            "sensor/1/wake",
            "sensor//prior",
            "nope",
        ] {
            assert_eq!(service_of_topic(bad), None, "{bad}");
        }
    }

    #[test]
    fn payloads_round_trip_and_trailing_bytes_are_refused() {
        let m = s2a::Measurement {
            header: Header {
                run: 7,
                episode: 3,
                step: 11,
                leg: 2,
                sender: 1,
                seq: 5,
            },
            dim: 2,
            sequence: 4,
            y: [0.25, -1.5, 0.0, 0.0, 0.0, 0.0],
        };
        let bytes = encode(&m).expect("encode");
        // Fixed-width legacy encoding: header (8+8+4·4) + 2·4 + 6·8 bytes.
        assert_eq!(bytes.len(), 32 + 8 + 48);
        assert_eq!(
            decode("measurement", &bytes).expect("decode"),
            Recorded::Measurement(m)
        );
        let mut long = bytes.clone();
        long.push(0);
        assert!(matches!(
            decode("measurement", &long),
            Err(RecordingError::Decode { .. })
        ));
        assert!(decode("measurement", &bytes[..bytes.len() - 1]).is_err());
        assert!(matches!(
            decode("sensor/9/wake", &bytes),
            Err(RecordingError::UnknownTopic(_))
        ));
    }
}
