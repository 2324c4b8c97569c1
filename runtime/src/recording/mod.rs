//! The MCAP recording format of a run (the processes and services: `crate::wire`): the one place
//! that names channels and schemas, encodes and decodes payloads, and reads a
//! recording leniently (an unfinished file from a crashed recorder too).
//!
//! * One channel per publish-subscribe service; its topic is the service name
//!   without the `etp/<run-id>/` prefix (`measurement`, `sensor/0/truth`, …).
//! * Format 7 (what the recorder writes): format 6's channels, each
//!   message's `publish_time` its sender's time (below).
//! * Format 6 (still read, as format 7): message encoding `protobuf`,
//!   schema encoding `protobuf`, schema name `etp.<Kind>`, schema data a
//!   serialized `FileDescriptorSet` built from the payload type and the
//!   catalogue's named fields (`wire::proto`, [`ProtoMapping::Typed`]), so
//!   any MCAP tool decodes every channel (Foxglove, the `mcap` CLIs,
//!   `mcap-protobuf-support`) and shows codes by name (`outcome: TARGET`,
//!   `sender: AGENT`, `degraded: false`) and arrays of the used length
//!   (`y` of a 2-D measurement: 2 values). [`protobuf`] is the codec.
//! * Format 5 (still read): the same channels in [`ProtoMapping::Plain`]:
//!   codes as plain integers, arrays written whole (6 values, 36 for a
//!   matrix). A protobuf channel is read as format 5 when its schema data is
//!   format 5's descriptor of its kind byte for byte ([`Encoding::of_channel`]).
//! * Format 4 and older (still read): message encoding
//!   [`LEGACY_MESSAGE_ENCODING`], bincode 2.0.1 through serde with
//!   `config::legacy()` (fixed-width little-endian integers, the field order
//!   of the `#[repr(C)]` struct, padding included), schema encoding
//!   [`LEGACY_SCHEMA_ENCODING`] (a text listing of the fields). Every
//!   message is decoded by its channel's encoding ([`Encoding`]), so both
//!   formats go through the same readers.
//! * Metadata records: [`META_RUN`] (format version, software version, run
//!   id, seed, episodes, scenario name, scenario content hash
//!   [`META_RUN_SCENARIO_HASH`]), [`META_SCENARIO`] (`toml`),
//!   [`META_STRATEGY`] (`json`), [`META_PREDICTION`] (`json`: what the
//!   strategy predicts, for "energy vs prediction"), [`META_CONFIG`]
//!   (`toml`: the run file), [`META_CHANNEL_SCHEDULE`] (`toml`, only for a
//!   run with channel changes).
//! * `log_time`: ns since the Unix epoch when the recorder took the sample
//!   off its subscriber; `publish_time` (format 7): when its sender
//!   published it, by the sender's clock (the sample's user header,
//!   `crate::wire::stamp`; a remote sensor's is its host's clock), in
//!   formats 6 and older the `log_time` again; `sequence`: per-channel
//!   count. Nothing is ordered by `publish_time` (`recordings/README.md`,
//!   "times").

use crate::wire::ServiceId;
#[cfg(test)]
use crate::wire::sensor_to_agent as s2a;

mod integrity;
mod layout;
pub mod observers;
pub mod ports;
pub mod protobuf;
mod read;
pub mod table;
mod verify;

pub use integrity::{META_RUN_SCENARIO_HASH, check_metadata};
pub use layout::{ChunkStats, Layout, layout};
pub use read::{Contents, RawMessage, ends_finished, read_lenient, stream_finished};
pub use verify::{Mismatch, PriorTable, VerifyReport, priors, verify};

/// The channels [`verify`] re-runs the estimator from (module `verify`):
/// `control` (the seed), `waypoint`, `slot`, `measurement`, `outcome`, and
/// per sensor `sensor/<i>/threshold`, `…/handover`, `…/truth`. Those that `c`
/// lacks (a filtered copy): verifying without them would blame the
/// estimator for what the copy left out. Empty without a readable
/// scenario (verify then says what is wrong with the metadata).
pub fn verify_missing_channels(c: &Contents) -> Vec<String> {
    let Some(sensors) = c
        .meta(META_SCENARIO, "toml")
        .and_then(|t| etp_shared::scenario::Scenario::from_toml(t).ok())
        .map(|s| s.sensors.len())
    else {
        return Vec::new();
    };
    let mut needed: Vec<String> = ["control", "waypoint", "slot", "measurement", "outcome"]
        .into_iter()
        .map(String::from)
        .collect();
    for i in 0..sensors {
        for what in ["threshold", "handover", "truth"] {
            needed.push(format!("sensor/{i}/{what}"));
        }
    }
    needed.retain(|t| !c.channels.contains_key(t));
    needed
}

/// Version of this format (metadata `etp.run` / `format_version`). 3: the
/// per-leg `handover` replaces the per-step `prior`, and `slot` carries the
/// sensor replica's prior digest; files written since issue 16 also hold the
/// `etp.config` record (the run's launch file) and schema texts with the
/// payload's size and Python `struct` format (readers need neither). 4: the
/// lossy radio (docs/MODEL.md §8): `slot` carries the slot's `attempts` and
/// `delivered`, `ledger` triggers, delivered and lost, and the agent's
/// `sensor/<i>/ack` is recorded. 5: the same messages encoded as protobuf
/// with `FileDescriptorSet` schemas. 6: protobuf enums for codes and ids,
/// `bool` flags, arrays cut to `dim` ([`ProtoMapping::Typed`]). 7: the same
/// channels, each message's `publish_time` the time its sender published it
/// (6 and older: the recorder's receive time, as `log_time`); formats 6, 5
/// and 4 are still read.
pub const FORMAT_VERSION: &str = "7";
/// The format of format 7's channels whose `publish_time` is the recorder's
/// receive time ([`Encoding::Protobuf`] too).
pub const PROTOBUF6_FORMAT_VERSION: &str = "6";
/// The protobuf format of plain integers and whole arrays ([`Encoding::Protobuf5`]).
pub const PROTOBUF5_FORMAT_VERSION: &str = "5";
/// The last format whose channels are bincode ([`LEGACY_MESSAGE_ENCODING`]).
pub const LEGACY_FORMAT_VERSION: &str = "4";
/// MCAP profile string.
pub const PROFILE: &str = "etpareto";
/// Message encoding of every channel (formats 5 to 7).
pub const MESSAGE_ENCODING: &str = "protobuf";
/// Schema encoding of every schema (formats 5 to 7).
pub const SCHEMA_ENCODING: &str = "protobuf";
/// Message encoding of format 4 and older (and of the bridge's link).
pub const LEGACY_MESSAGE_ENCODING: &str = crate::wire::catalogue::PAYLOAD_ENCODING;
/// Schema encoding of format 4 and older.
pub const LEGACY_SCHEMA_ENCODING: &str = "etp-field-list";
/// Metadata record names.
pub const META_RUN: &str = "etp.run";
pub const META_SCENARIO: &str = "etp.scenario";
pub const META_STRATEGY: &str = "etp.strategy";
pub const META_PREDICTION: &str = "etp.prediction";
/// The run's configuration (`toml`: the `etp run --config` file, or the
/// flags of the run written as one).
pub const META_CONFIG: &str = "etp.config";
/// The run's channel changes (`toml`: `etp run --channel-schedule`, every
/// key written out; docs/MODEL.md §8.8), when it had any: `replay verify`
/// draws each sensor's attempts on the link in force.
pub const META_CHANNEL_SCHEDULE: &str = "etp.channel_schedule";

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

pub use crate::wire::proto::ProtoMapping;
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

/// How a channel's payloads are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// `protobuf` in [`ProtoMapping::Typed`] (formats 7 and 6): what the
    /// recorder writes.
    Protobuf,
    /// `protobuf` in [`ProtoMapping::Plain`] (format 5).
    Protobuf5,
    /// `bincode2-serde-legacy` (format 4 and older; the bridge's link).
    Bincode,
}

impl Encoding {
    /// The encoding of a channel's `message_encoding` as this etp writes
    /// it (`protobuf`: formats 7 and 6); `None` for one etp does not write (a
    /// channel of another MCAP writer).
    pub fn of(message_encoding: &str) -> Option<Self> {
        match message_encoding {
            MESSAGE_ENCODING => Some(Self::Protobuf),
            LEGACY_MESSAGE_ENCODING => Some(Self::Bincode),
            _ => None,
        }
    }

    /// The encoding of a channel of a file: as [`Encoding::of`], and a
    /// `protobuf` channel whose schema data is format 5's descriptor of its
    /// topic's kind, byte for byte, is [`Encoding::Protobuf5`] (both
    /// formats name their schemas `etp.<Kind>`; format 5's descriptors are
    /// built by the same code, in [`ProtoMapping::Plain`]).
    pub fn of_channel(message_encoding: &str, topic: &str, schema_data: &[u8]) -> Option<Self> {
        let encoding = Self::of(message_encoding)?;
        let format5 = encoding == Self::Protobuf
            && kind_of_topic(topic)
                .and_then(|k| k.proto_schema_in(ProtoMapping::Plain).ok())
                .is_some_and(|plain| plain == schema_data);
        Some(if format5 { Self::Protobuf5 } else { encoding })
    }

    /// The channel's `message_encoding`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Protobuf | Self::Protobuf5 => MESSAGE_ENCODING,
            Self::Bincode => LEGACY_MESSAGE_ENCODING,
        }
    }

    /// The newest recording format whose channels are in this encoding.
    pub fn format_version(self) -> &'static str {
        match self {
            Self::Protobuf => FORMAT_VERSION,
            Self::Protobuf5 => PROTOBUF5_FORMAT_VERSION,
            Self::Bincode => LEGACY_FORMAT_VERSION,
        }
    }

    /// Every recording format whose channels are in this encoding (formats
    /// 7 and 6 differ only in what `publish_time` is).
    pub fn format_versions(self) -> &'static [&'static str] {
        match self {
            Self::Protobuf => &[FORMAT_VERSION, PROTOBUF6_FORMAT_VERSION],
            Self::Protobuf5 => &[PROTOBUF5_FORMAT_VERSION],
            Self::Bincode => &[LEGACY_FORMAT_VERSION],
        }
    }

    /// The protobuf mapping of a protobuf encoding.
    pub fn proto_mapping(self) -> Option<ProtoMapping> {
        match self {
            Self::Protobuf => Some(ProtoMapping::Typed),
            Self::Protobuf5 => Some(ProtoMapping::Plain),
            Self::Bincode => None,
        }
    }

    /// The schema encoding and data of a channel of `kind` in this encoding.
    pub fn schema(self, kind: Kind) -> Result<(String, &'static str, Vec<u8>), RecordingError> {
        Ok(match self.proto_mapping() {
            Some(mapping) => (
                kind.proto_name(),
                SCHEMA_ENCODING,
                kind.proto_schema_in(mapping)
                    .map_err(RecordingError::Encode)?
                    .to_vec(),
            ),
            None => (
                kind.schema_name().to_string(),
                LEGACY_SCHEMA_ENCODING,
                kind.schema_text().into_bytes(),
            ),
        })
    }

    /// Encode one payload.
    pub fn encode<T: crate::wire::Message>(self, payload: &T) -> Result<Vec<u8>, RecordingError> {
        match self.proto_mapping() {
            Some(mapping) => protobuf::encode(payload, mapping)
                .map_err(|e| RecordingError::Encode(e.to_string())),
            None => bincode::serde::encode_to_vec(payload, cfg())
                .map_err(|e| RecordingError::Encode(e.to_string())),
        }
    }

    /// Encode one decoded payload, whatever its kind.
    pub fn encode_recorded(self, r: &Recorded) -> Result<Vec<u8>, RecordingError> {
        struct Enc<'a>(Encoding, &'a Recorded);
        impl crate::wire::KindVisitor for Enc<'_> {
            type Out = Result<Vec<u8>, RecordingError>;
            fn visit<T: crate::wire::Message>(self) -> Self::Out {
                let v = T::from_recorded(self.1.clone()).ok_or_else(|| {
                    RecordingError::Encode(format!("a {:?} payload", self.1.kind()))
                })?;
                self.0.encode(&v)
            }
        }
        r.kind().visit(Enc(self, r))
    }

    /// Decode one payload of a channel (THE decoder of the recording).
    pub fn decode(self, topic: &str, data: &[u8]) -> Result<Recorded, RecordingError> {
        struct Decode<'a>(Encoding, &'a str, &'a [u8]);
        impl crate::wire::KindVisitor for Decode<'_> {
            type Out = Result<Recorded, RecordingError>;
            fn visit<T: crate::wire::Message>(self) -> Self::Out {
                let r = match self.0.proto_mapping() {
                    Some(mapping) => {
                        protobuf::decode::<T>(self.2, mapping).map_err(|e| e.to_string())
                    }
                    None => dec::<T>(self.2),
                };
                r.map(T::into_recorded)
                    .map_err(|reason| RecordingError::Decode {
                        topic: self.1.to_string(),
                        reason,
                    })
            }
        }
        let kind =
            kind_of_topic(topic).ok_or_else(|| RecordingError::UnknownTopic(topic.into()))?;
        kind.visit(Decode(self, topic, data))
    }
}

fn cfg() -> bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Fixint,
    bincode::config::NoLimit,
> {
    bincode::config::legacy()
}

/// Encode one payload as the recorder writes it (protobuf, [`ProtoMapping::Typed`]).
pub fn encode<T: crate::wire::Message>(payload: &T) -> Result<Vec<u8>, RecordingError> {
    Encoding::Protobuf.encode(payload)
}

fn dec<T: serde::de::DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    let (v, used) = bincode::serde::decode_from_slice(data, cfg()).map_err(|e| e.to_string())?;
    if used != data.len() {
        return Err(format!("{} trailing bytes", data.len() - used));
    }
    Ok(v)
}

/// Decode one payload of a channel in the current format (protobuf); a
/// message read from a file is decoded by its own channel's encoding
/// ([`RawMessage::decode`]).
pub fn decode(topic: &str, data: &[u8]) -> Result<Recorded, RecordingError> {
    Encoding::Protobuf.decode(topic, data)
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
        for enc in [Encoding::Protobuf, Encoding::Protobuf5, Encoding::Bincode] {
            let bytes = enc.encode(&m).expect("encode");
            if enc == Encoding::Bincode {
                // Fixed-width legacy encoding: header (8+8+4·4) + 2·4 + 6·8 bytes.
                assert_eq!(bytes.len(), 32 + 8 + 48);
            }
            assert_eq!(
                enc.decode("measurement", &bytes).expect("decode"),
                Recorded::Measurement(m)
            );
            let mut long = bytes.clone();
            long.push(0);
            assert!(matches!(
                enc.decode("measurement", &long),
                Err(RecordingError::Decode { .. })
            ));
            assert!(
                enc.decode("measurement", &bytes[..bytes.len() - 1])
                    .is_err()
            );
            // One format's bytes are no other's.
            for other in [Encoding::Protobuf, Encoding::Protobuf5, Encoding::Bincode] {
                if other != enc {
                    assert!(
                        other.decode("measurement", &bytes).is_err(),
                        "{enc:?} as {other:?}"
                    );
                }
            }
        }
        let bytes = encode(&m).expect("encode");
        assert!(matches!(
            decode("sensor/9/wake", &bytes),
            Err(RecordingError::UnknownTopic(_))
        ));
    }
}
