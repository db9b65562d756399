//! Renders the message table ([`crate::message::spec::MESSAGES`]) as a DBC file, the format
//! CAN tools (cantools, SavvyCAN, Vector CANdb++) read.
//!
//! `protocol/scanhil.dbc` is this function's output, committed; a test fails when the two
//! differ (regenerate with `cargo run -p scanhil-protocol --example write-dbc`), and another
//! parses the file with the `can-dbc` crate and compares every signal with the table.
//! FD messages carry the Vector attribute `VFrameFormat` = `StandardCAN_FD`.

use std::fmt::Write;

use crate::message::spec::{MESSAGES, MessageSpec, Sender, SignalSpec};

/// The DBC nodes, in order.
const NODES: [Sender; 3] = [Sender::Controller, Sender::Fsm, Sender::Sensor];
/// Index of `StandardCAN_FD` in the `VFrameFormat` enum below.
const VFRAME_FORMAT_STANDARD_FD: u8 = 14;

/// The whole DBC file for the message set.
#[must_use]
pub fn render() -> String {
    let mut out = String::new();
    out.push_str("VERSION \"scanhil 1\"\n\n\nNS_ :\n\tCM_\n\tBA_DEF_\n\tBA_\n\tVAL_\n\tBA_DEF_DEF_\n\nBS_:\n\n");
    let names: Vec<&str> = NODES.iter().map(|n| n.dbc_name()).collect();
    let _ = writeln!(out, "BU_: {}\n", names.join(" "));
    for message in MESSAGES {
        render_message(&mut out, message);
    }
    for message in MESSAGES {
        let _ = writeln!(out, "CM_ BO_ {} \"{}\";", message.id, message.comment);
        for signal in message.signals {
            let _ = writeln!(
                out,
                "CM_ SG_ {} {} \"{}\";",
                message.id, signal.name, signal.comment
            );
        }
    }
    out.push_str(concat!(
        "BA_DEF_ BO_ \"VFrameFormat\" ENUM \"StandardCAN\",\"ExtendedCAN\",\"reserved\",",
        "\"J1939PG\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",",
        "\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"StandardCAN_FD\",",
        "\"ExtendedCAN_FD\";\n",
        "BA_DEF_ \"BusType\" STRING ;\n",
        "BA_DEF_DEF_ \"VFrameFormat\" \"StandardCAN\";\n",
        "BA_DEF_DEF_ \"BusType\" \"CAN FD\";\n",
        "BA_ \"BusType\" \"CAN FD\";\n",
    ));
    for message in MESSAGES.iter().filter(|m| m.fd) {
        let _ = writeln!(
            out,
            "BA_ \"VFrameFormat\" BO_ {} {VFRAME_FORMAT_STANDARD_FD};",
            message.id
        );
    }
    for message in MESSAGES {
        for signal in message.signals.iter().filter(|s| !s.choices.is_empty()) {
            let _ = write!(out, "VAL_ {} {}", message.id, signal.name);
            for (value, name) in signal.choices {
                let _ = write!(out, " {value} \"{name}\"");
            }
            out.push_str(" ;\n");
        }
    }
    out
}

fn render_message(out: &mut String, message: &MessageSpec) {
    let _ = writeln!(
        out,
        "BO_ {} {}: {} {}",
        message.id,
        message.name,
        message.len,
        message.sender.dbc_name()
    );
    let receivers: Vec<&str> = NODES
        .iter()
        .filter(|&&n| n != message.sender)
        .map(|n| n.dbc_name())
        .collect();
    for signal in message.signals {
        let _ = writeln!(
            out,
            " SG_ {} : {}|{}@1{} ({},{}) [{}|{}] \"{}\" {}",
            signal.name,
            signal.start_bit,
            signal.length,
            if signal.signed { '-' } else { '+' },
            number(signal.scale, signal),
            number(signal.offset, signal),
            number(signal.min(), signal),
            number(signal.max(), signal),
            signal.unit,
            receivers.join(",")
        );
    }
    out.push('\n');
}

/// A number with as many decimals as the signal's scale has (so `1e-6 * 8388607` prints as
/// `8.388607`, not with binary rounding noise).
fn number(value: f64, signal: &SignalSpec) -> String {
    let mut decimals = 0;
    while decimals < 15 && (signal.scale * 10f64.powi(decimals)).fract().abs() > 1e-9 {
        decimals += 1;
    }
    format!("{value:.prec$}", prec = decimals as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_limits_print_without_rounding_noise() {
        let text = render();
        assert!(
            text.contains(
                " SG_ CurrentA : 16|24@1- (0.000001,0.000000) [-8.388608|8.388607] \"A\""
            ),
            "{text}"
        );
        assert!(text.contains(" SG_ Seq : 0|16@1+ (1,0) [0|65535] \"\""));
        assert!(text.contains("BA_ \"VFrameFormat\" BO_ 320 14;"));
    }
}
