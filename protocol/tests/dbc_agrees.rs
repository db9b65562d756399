//! `protocol/scanhil.dbc` describes exactly the Rust message table: parsed with `can-dbc`
//! (an independent parser), every id, name, length, sender, signal position, length, byte
//! order, signedness, scale, offset, range and unit must agree.

use can_dbc::{ByteOrder, Dbc, MessageId, NumericValue, ValueType};
use scanhil_protocol::message::spec::MESSAGES;

const DBC_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scanhil.dbc");

fn committed_dbc() -> String {
    std::fs::read_to_string(DBC_PATH).expect("protocol/scanhil.dbc is readable")
}

fn numeric(value: NumericValue) -> f64 {
    match value {
        NumericValue::Uint(v) => v as f64,
        NumericValue::Int(v) => v as f64,
        NumericValue::Double(v) => v,
    }
}

#[test]
fn committed_file_is_the_rendered_table() {
    assert!(
        committed_dbc() == scanhil_protocol::dbc::render(),
        "protocol/scanhil.dbc is stale: run `cargo run -p scanhil-protocol --example write-dbc`"
    );
}

#[test]
fn can_dbc_reads_the_same_messages_and_signals() {
    let text = committed_dbc();
    let dbc = Dbc::try_from(text.as_str()).expect("can-dbc parses scanhil.dbc");
    assert_eq!(dbc.messages.len(), MESSAGES.len());
    for spec in MESSAGES {
        let message = dbc
            .messages
            .iter()
            .find(|m| m.id == MessageId::Standard(spec.id))
            .unwrap_or_else(|| panic!("{} ({:#x}) missing from the DBC", spec.name, spec.id));
        assert_eq!(message.name, spec.name);
        assert_eq!(message.size, u64::from(spec.len), "{}", spec.name);
        assert_eq!(message.transmitter.as_deref(), Some(spec.sender.dbc_name()));
        assert_eq!(message.signals.len(), spec.signals.len(), "{}", spec.name);
        for (signal, want) in message.signals.iter().zip(spec.signals) {
            let at = format!("{}.{}", spec.name, want.name);
            assert_eq!(signal.name, want.name, "{at}");
            assert_eq!(signal.start_bit, u64::from(want.start_bit), "{at}");
            assert_eq!(signal.size, u64::from(want.length), "{at}");
            assert_eq!(signal.byte_order, ByteOrder::LittleEndian, "{at}");
            let value_type = if want.signed {
                ValueType::Signed
            } else {
                ValueType::Unsigned
            };
            assert_eq!(signal.value_type, value_type, "{at}");
            assert_eq!(signal.factor, want.scale, "{at}");
            assert_eq!(signal.offset, want.offset, "{at}");
            assert!(
                (numeric(signal.min) - want.min()).abs() <= want.scale * 1e-6,
                "{at}"
            );
            assert!(
                (numeric(signal.max) - want.max()).abs() <= want.scale * 1e-6,
                "{at}"
            );
            assert_eq!(signal.unit, want.unit, "{at}");
        }
    }
}

#[test]
fn fd_messages_are_marked_fd_in_the_dbc() {
    let text = committed_dbc();
    let dbc = Dbc::try_from(text.as_str()).expect("can-dbc parses scanhil.dbc");
    for spec in MESSAGES {
        let marked = dbc.attribute_values_message.iter().any(|a| {
            a.name == "VFrameFormat"
                && a.message_id == MessageId::Standard(spec.id)
                && matches!(a.value, can_dbc::AttributeValue::Uint(14))
        });
        assert_eq!(marked, spec.fd, "{}", spec.name);
    }
}
