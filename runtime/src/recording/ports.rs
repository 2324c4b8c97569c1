//! Ports of any kind of the catalogue, typed at run time: a subscriber that
//! yields the payloads encoded in the recording's encoding, and a publisher
//! that takes them decoded. The recorder (encoded subscribers), `etp replay
//! --publish` (publishers) and the Zenoh bridge (both: what crosses a host
//! boundary is a payload encoded as format-4 recordings held it, bincode,
//! whose fixed sizes the traffic counts use, behind its sender's time) open
//! their ports here. Every payload comes with its sender's time
//! ([`PublishTime`], the sample's user header).

use super::{Encoding, RecordingError};
use crate::wire::stamp::{PublishTime, now_ns};
use crate::wire::{
    Header, Kind, KindVisitor, Message, PortError, Ports, Recorded, ServiceId, WireError,
};

/// A subscriber of one service, whatever its payload type.
pub trait EncodedSubscriber {
    /// Append every waiting payload, decoded (a copy: cheap), with its
    /// sender's time, so a reader that encodes slowly (the recorder:
    /// protobuf) empties the service's queue first and encodes afterwards.
    fn take(&self, out: &mut Vec<(PublishTime, Recorded)>) -> Result<(), RecordingError>;

    /// Append every waiting payload, encoded in `encoding` (the bridge's
    /// link: bincode), with its header and its sender's time.
    fn drain(
        &self,
        encoding: Encoding,
        out: &mut Vec<(Header, PublishTime, Vec<u8>)>,
    ) -> Result<(), RecordingError>;

    /// Attach to every publisher of the service now (without receiving):
    /// from then on, a publisher that ends leaves what it sent to this
    /// subscriber (see `recording::observers`).
    fn attach(&self) -> Result<(), RecordingError>;
}

impl<T: Message> EncodedSubscriber for crate::wire::Sub<T> {
    fn attach(&self) -> Result<(), RecordingError> {
        use iceoryx2::port::update_connections::UpdateConnections;
        self.update_connections()
            .map_err(|e| PortError::receive("subscriber", e).into())
    }

    fn take(&self, out: &mut Vec<(PublishTime, Recorded)>) -> Result<(), RecordingError> {
        while let Some(s) = self
            .receive()
            .map_err(|e| PortError::receive("subscriber", e))?
        {
            let v: T = *s;
            out.push((*s.user_header(), v.into_recorded()));
        }
        Ok(())
    }

    fn drain(
        &self,
        encoding: Encoding,
        out: &mut Vec<(Header, PublishTime, Vec<u8>)>,
    ) -> Result<(), RecordingError> {
        while let Some(s) = self
            .receive()
            .map_err(|e| PortError::receive("subscriber", e))?
        {
            let v: T = *s;
            out.push((*v.header(), *s.user_header(), encoding.encode(&v)?));
        }
        Ok(())
    }
}

/// A publisher of one service, whatever its payload type.
pub trait DecodedPublisher {
    /// Send one decoded payload (of this service's kind) stamped with the
    /// time now, as its sender (`etp replay publish`); the number of
    /// subscribers it reached.
    fn send(&self, r: Recorded) -> Result<usize, RecordingError> {
        self.send_at(r, now_ns())
    }

    /// Send one decoded payload stamped with `time`, when another host's
    /// sender published it (the bridge).
    fn send_at(&self, r: Recorded, time: PublishTime) -> Result<usize, RecordingError>;
}

impl<T: Message> DecodedPublisher for crate::wire::Pub<T> {
    fn send_at(&self, r: Recorded, time: PublishTime) -> Result<usize, RecordingError> {
        let kind = r.kind();
        let v = T::from_recorded(r).ok_or_else(|| RecordingError::Decode {
            topic: format!("{:?}", T::KIND),
            reason: format!("a {kind:?} payload on a {:?} port", T::KIND),
        })?;
        self.publish_at(v, time)
            .map_err(|e| PortError::send("publisher", e).into())
    }
}

fn kind_of(s: ServiceId) -> Result<Kind, WireError> {
    s.kind()
        .ok_or_else(|| WireError::Port(format!("{s:?}"), "not a publish-subscribe service".into()))
}

/// Open a subscriber of `s` (an observer's, with the observer buffer, when
/// `observer`: the recorder; else the reader's own port: the bridge stands
/// in for a remote reader).
pub fn encoded_subscriber(
    ports: &Ports<'_>,
    s: ServiceId,
    observer: bool,
) -> Result<Box<dyn EncodedSubscriber>, WireError> {
    struct Open<'a, 'p>(&'a Ports<'p>, ServiceId, bool);
    impl KindVisitor for Open<'_, '_> {
        type Out = Result<Box<dyn EncodedSubscriber>, WireError>;
        fn visit<T: Message>(self) -> Self::Out {
            Ok(if self.2 {
                Box::new(self.0.observer::<T>(self.1)?)
            } else {
                Box::new(self.0.subscriber::<T>(self.1)?)
            })
        }
    }
    kind_of(s)?.visit(Open(ports, s, observer))
}

/// Open a publisher of `s`, typed by its kind.
pub fn decoded_publisher(
    ports: &Ports<'_>,
    s: ServiceId,
) -> Result<Box<dyn DecodedPublisher>, WireError> {
    struct Open<'a, 'p>(&'a Ports<'p>, ServiceId);
    impl KindVisitor for Open<'_, '_> {
        type Out = Result<Box<dyn DecodedPublisher>, WireError>;
        fn visit<T: Message>(self) -> Self::Out {
            Ok(Box::new(self.0.publisher::<T>(self.1)?))
        }
    }
    kind_of(s)?.visit(Open(ports, s))
}
