//! The MCAP recording format of a run (ARCHITECTURE.md "Runtime processes and services", recording): the one place
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

use crate::wire::ServiceId;
#[cfg(test)]
use crate::wire::sensor_to_agent as s2a;

mod integrity;
mod layout;
pub mod ports;
mod read;
pub mod table;
mod verify;

pub use integrity::{META_RUN_SCENARIO_HASH, check_metadata};
pub use layout::{ChunkStats, Layout, layout};
pub use read::{Contents, RawMessage, ends_finished, read_lenient, stream_finished};
pub use verify::{Mismatch, PriorTable, VerifyReport, priors, verify};

/// Version of this format (metadata `etp.run` / `format_version`). 3: the
/// per-leg `handover` replaces the per-step `prior`, and `slot` carries the
/// sensor replica's prior digest; files written since issue 16 also hold the
/// `etp.config` record (the run's launch file) and schema texts with the
/// payload's size and Python `struct` format (readers need neither). 4: the
/// lossy radio (docs/MODEL.md §8): `slot` carries the slot's `attempts` and
/// `delivered`, `ledger` triggers, delivered and lost, and the agent's
/// `sensor/<i>/ack` is recorded.
pub const FORMAT_VERSION: &str = "4";
/// MCAP profile string.
pub const PROFILE: &str = "etpareto";
/// Message encoding of every channel.
pub const MESSAGE_ENCODING: &str = crate::wire::catalogue::PAYLOAD_ENCODING;
/// Schema encoding of every schema.
pub const SCHEMA_ENCODING: &str = "etp-field-list";
/// Metadata record names.
pub const META_RUN: &str = "etp.run";
pub const META_SCENARIO: &str = "etp.scenario";
pub const META_STRATEGY: &str = "etp.strategy";
pub const META_PREDICTION: &str = "etp.prediction";
/// The run's configuration (`toml`: the `etp run --config` file, or the
/// flags of the run written as one).
pub const META_CONFIG: &str = "etp.config";

/// Where `etp replay publish` leaves the metadata of the recording it
/// publishes, for a recorder of that run started without `--meta` (it
/// writes them when it finishes): a file in the run's iceoryx2 folder, which
/// lives as long as one of the run's processes does.
pub fn handover_path(run: &crate::wire::RunId) -> std::path::PathBuf {
    run.root_dir().join("etp-metadata.json")
}

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
    #[error(transparent)]
    Port(#[from] crate::wire::PortError),
}

pub use crate::wire::{Kind, Recorded};

/// The channel topic of a service (its name without `etp/<run-id>/`), and
/// the kind it carries; `None` for event services (not recorded).
pub fn channel(service: ServiceId) -> Option<(String, Kind)> {
    Some((service.topic(), service.kind()?))
}

/// The service a channel topic was recorded from (the inverse of [`channel`]).
pub fn service_of_topic(topic: &str) -> Option<ServiceId> {
    ServiceId::from_topic(topic)
}

/// The kind of a channel topic.
pub fn kind_of_topic(topic: &str) -> Option<Kind> {
    service_of_topic(topic)?.kind()
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
    struct Decode<'a>(&'a str, &'a [u8]);
    impl crate::wire::KindVisitor for Decode<'_> {
        type Out = Result<Recorded, RecordingError>;
        fn visit<T: crate::wire::Message>(self) -> Self::Out {
            dec::<T>(self.0, self.1).map(T::into_recorded)
        }
    }
    let kind = kind_of_topic(topic).ok_or_else(|| RecordingError::UnknownTopic(topic.into()))?;
    kind.visit(Decode(topic, data))
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
            "sensor//handover",
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
