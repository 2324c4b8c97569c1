//! Format 6's mapping: codes and ids as enums, flags as `bool`, arrays of
//! `dim` entries per axis; every payload still round-trips bit for bit.

use super::super::*;
use super::header;
use crate::wire::{
    Header, SENDER_AGENT, agent_to_coordinator as a2c, agent_to_sensor as a2s,
    sensor_to_agent as s2a,
};

const TYPED: ProtoMapping = ProtoMapping::Typed;

fn message(kind: crate::wire::Kind, bytes: &[u8]) -> DynamicMessage {
    let desc = kind.proto_descriptor_in(TYPED).expect("descriptor");
    DynamicMessage::decode(desc, bytes).expect("valid protobuf")
}

/// The enum value's name of field `name` of `m`.
fn enum_name(m: &DynamicMessage, name: &str) -> Option<String> {
    let field = m.descriptor().get_field_by_name(name)?;
    let PKind::Enum(e) = field.kind() else {
        return None;
    };
    let Value::EnumNumber(n) = m.get_field(&field).into_owned() else {
        return None;
    };
    e.get_value(n).map(|v| v.name().to_string())
}

#[test]
fn arrays_hold_dim_entries_per_axis_and_come_back_whole() {
    let mut cov = [[0.0; 6]; 6];
    cov[0] = [2.0, -0.0, 0.0, 0.0, 0.0, 0.0];
    cov[1] = [f64::NAN, 3.5, 0.0, 0.0, 0.0, 0.0];
    let h = a2s::Handover {
        header: header(),
        dim: 2,
        _pad: 0,
        mean: [0.36, -0.0, 0.0, 0.0, 0.0, 0.0],
        cov,
    };
    let bytes = encode(&h, TYPED).expect("encode");
    let m = message(crate::wire::Kind::Handover, &bytes);
    let len = |name: &str| match m.get_field_by_name(name).as_deref() {
        Some(Value::List(l)) => l.len(),
        other => panic!("{name}: {other:?}"),
    };
    assert_eq!((len("mean"), len("cov")), (2, 4));
    let back: a2s::Handover = decode(&bytes, TYPED).expect("decode");
    let bits = |m: &a2s::Handover| {
        m.cov
            .iter()
            .flatten()
            .chain(&m.mean)
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&back), bits(&h));
    // The format-5 message of the same payload is 6 + 36 values, and is
    // not a format-6 one.
    let plain = encode(&h, ProtoMapping::Plain).expect("plain");
    assert!(plain.len() > bytes.len() + 8 * 30);
    assert!(decode::<a2s::Handover>(&plain, TYPED).is_err());

    // An entry past dim could not be read back: refused, not dropped.
    let mut past = h;
    past.mean[2] = 1.0;
    assert!(encode(&past, TYPED).is_err());
    let mut past = h;
    past.cov[4][4] = -0.0;
    assert!(encode(&past, TYPED).is_err());
    // A dim past the array's length is refused too.
    let wide = a2s::Truth {
        header: header(),
        dim: 7,
        _pad: 0,
        x: [1.0; 6],
    };
    assert!(encode(&wide, TYPED).is_err());

    // A message whose array holds more or fewer than dim values: refused.
    let t = a2s::Truth {
        header: header(),
        dim: 2,
        _pad: 0,
        x: [0.36, 0.65, 0.0, 0.0, 0.0, 0.0],
    };
    let tb = encode(&t, TYPED).expect("encode");
    let mut m = message(crate::wire::Kind::Truth, &tb);
    for n in [1, 3, 6] {
        m.set_field_by_name("x", Value::List(vec![Value::F64(0.5); n]));
        assert!(
            decode::<a2s::Truth>(&m.encode_to_vec(), TYPED).is_err(),
            "{n} values for dim 2"
        );
    }
    // dim 0: no values at all.
    let empty = a2s::Truth {
        dim: 0,
        x: [0.0; 6],
        ..t
    };
    let eb = encode(&empty, TYPED).expect("encode");
    assert_eq!(decode::<a2s::Truth>(&eb, TYPED).expect("decode"), empty);
}

#[test]
fn codes_and_ids_are_enums_flags_are_bools_and_every_value_round_trips() {
    let o = a2c::Outcome {
        header: Header {
            sender: SENDER_AGENT,
            ..header()
        },
        outcome: 1,
        degraded: 1,
        steps: 40,
        dead_sensor: u32::MAX,
        ..a2c::Outcome::default()
    };
    let bytes = encode(&o, TYPED).expect("encode");
    let m = message(crate::wire::Kind::Outcome, &bytes);
    assert_eq!(enum_name(&m, "outcome").as_deref(), Some("TARGET"));
    assert_eq!(enum_name(&m, "dead_sensor").as_deref(), Some("NONE"));
    assert_eq!(
        m.get_field_by_name("degraded").as_deref(),
        Some(&Value::Bool(true))
    );
    let Some(Value::Message(h)) = m.get_field_by_name("header").as_deref().cloned() else {
        panic!("no header")
    };
    assert_eq!(enum_name(&h, "sender").as_deref(), Some("AGENT"));
    assert_eq!(decode::<a2c::Outcome>(&bytes, TYPED).expect("decode"), o);

    // A code or id no enum value names is kept as its number (open enums).
    let odd = a2c::Outcome {
        header: Header {
            sender: 70,
            ..header()
        },
        outcome: 9,
        dead_sensor: 3,
        degraded: 0,
        ..o
    };
    let ob = encode(&odd, TYPED).expect("encode");
    assert_eq!(decode::<a2c::Outcome>(&ob, TYPED).expect("decode"), odd);
    assert_eq!(
        enum_name(&message(crate::wire::Kind::Outcome, &ob), "dead_sensor").as_deref(),
        Some("SENSOR_3")
    );
    // A flag that is neither 0 nor 1 could not be kept in a bool: refused.
    let flag2 = s2a::Slot {
        header: header(),
        delivered: 2,
        ..s2a::Slot::default()
    };
    assert!(encode(&flag2, TYPED).is_err());
    assert!(encode(&flag2, ProtoMapping::Plain).is_ok());
}
