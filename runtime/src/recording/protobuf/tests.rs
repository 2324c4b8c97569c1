//! The codec's round trip, bit for bit, and what it refuses, in both
//! mappings (format 5's plain one here, format 6's typed one in `typed`).

use super::*;
use crate::wire::{Header, agent_to_sensor as a2s, coordinator_to_sensor as c2s};

mod typed;

const PLAIN: ProtoMapping = ProtoMapping::Plain;

fn header() -> Header {
    Header {
        run: u64::MAX - 3,
        episode: 3,
        step: 11,
        leg: 2,
        sender: 0xFFFF_0001,
        seq: 5,
    }
}

#[test]
fn payloads_round_trip_bit_for_bit_and_other_bytes_are_refused() {
    let mut cov = [[0.0; 6]; 6];
    for (r, row) in cov.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = (r as f64 + 1.0) / (c as f64 + 3.0);
        }
    }
    cov[5][5] = f64::NAN;
    cov[0][5] = -0.0;
    cov[1][5] = f64::INFINITY;
    cov[2][5] = f64::MIN_POSITIVE / 2.0;
    let h = a2s::Handover {
        header: header(),
        dim: 6,
        _pad: 0,
        mean: [0.1, -2.5e300, 3.0, 0.0, 5.0, 6.0],
        cov,
    };
    let bytes = encode(&h, PLAIN).expect("encode");
    let back: a2s::Handover = decode(&bytes, PLAIN).expect("decode");
    // Bit for bit, NaN, −0 and subnormals included.
    let bits = |m: &a2s::Handover| {
        m.cov
            .iter()
            .flatten()
            .chain(&m.mean)
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&back), bits(&h));
    assert_eq!(back.header, h.header);
    assert_eq!(back.dim, 6);

    // Trailing garbage, a cut, a field appended, a short vector: refused.
    let mut long = bytes.clone();
    long.extend_from_slice(&[0x08, 0x01]);
    assert!(decode::<a2s::Handover>(&long, PLAIN).is_err());
    assert!(decode::<a2s::Handover>(&bytes[..bytes.len() - 1], PLAIN).is_err());
    let mut extra = bytes.clone();
    extra.extend_from_slice(&[0xF8, 0x01, 0x07]); // field 31, varint 7
    assert!(decode::<a2s::Handover>(&extra, PLAIN).is_err());
    let t = a2s::Truth {
        header: header(),
        dim: 2,
        _pad: 0,
        x: [1.0; 6],
    };
    let tb = encode(&t, PLAIN).expect("encode");
    // The same message with a 5-entry `x`: re-encoded by hand via the
    // descriptor, so the bytes are valid protobuf.
    let desc = t_desc();
    let mut m = DynamicMessage::decode(desc, tb.as_slice()).expect("decodes");
    m.set_field_by_name("x", Value::List(vec![Value::F64(1.0); 5]));
    let short = m.encode_to_vec();
    let e = decode::<a2s::Truth>(&short, PLAIN).expect_err("short vector");
    assert!(e.to_string().contains("only 5 values"), "{e}");
    // Garbage never panics.
    for n in 0..64u8 {
        let g: Vec<u8> = (0..n).map(|i| i.wrapping_mul(37).wrapping_add(n)).collect();
        for mapping in ProtoMapping::ALL {
            let _ = decode::<a2s::Truth>(&g, mapping);
        }
    }
    // Arrays are written whole even when zero: bytes without them are refused.
    assert!(decode::<a2s::Truth>(&[], PLAIN).is_err());
    // The header is always written, even all zero (a message field has
    // presence): the empty byte string is not a payload.
    let ack = a2s::Ack::default();
    assert_eq!(encode(&ack, PLAIN).expect("encode"), vec![0x0A, 0x00]);
    assert_eq!(decode::<a2s::Ack>(&[0x0A, 0x00], PLAIN).expect("zero"), ack);
    assert!(decode::<a2s::Ack>(&[], PLAIN).is_err());
}

fn t_desc() -> MessageDescriptor {
    crate::wire::Kind::Truth
        .proto_descriptor_in(PLAIN)
        .expect("descriptor")
}

#[test]
fn negative_zero_in_a_scalar_is_refused_not_lost() {
    let t = c2s::Threshold {
        header: header(),
        delta: -0.0,
        ..c2s::Threshold::default()
    };
    assert!(encode(&t, PLAIN).is_err());
    let t = c2s::Threshold { delta: 0.0, ..t };
    let back: c2s::Threshold = decode(&encode(&t, PLAIN).expect("encode"), PLAIN).expect("decode");
    assert_eq!(back.delta.to_bits(), 0);
}

#[test]
fn non_zero_padding_is_refused_not_lost() {
    let t = c2s::Threshold {
        header: header(),
        kind: 1,
        sensor: 0,
        delta_index: 2,
        _pad: 7,
        delta: 0.5,
    };
    assert!(encode(&t, PLAIN).is_err());
}
