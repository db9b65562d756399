//! Prints the bus budget of the loop's message set: worst-case bits per frame and the
//! highest loop rate each bus configuration carries (the numbers in `docs/protocol.md`).
//! `cargo run -p scanhil-protocol --example bus-budget`.

use scanhil_protocol::bus_load::{Bitrates, BusLoad, LoadLimits, Traffic};
use scanhil_protocol::message::{ids, spec::message_spec};

fn main() {
    let spec = |id| message_spec(id).expect("the id is in the message set");
    let classical = [
        spec(ids::COIL_COMMAND),
        spec(ids::STEP),
        spec(ids::ANGLE_READING),
        spec(ids::DISTANCE),
    ];
    let fd = [spec(ids::COMMAND_STEP_FD), spec(ids::ANGLES_DISTANCE_FD)];
    let configs = [
        ("classical 1 Mbit/s", &classical[..], Bitrates::CLASSICAL_1M),
        ("FD 1 / 5 Mbit/s", &fd[..], Bitrates::FD_1M_5M),
        (
            "FD 1 / 8 Mbit/s",
            &fd[..],
            Bitrates {
                nominal_bps: 1e6,
                data_bps: 8e6,
            },
        ),
    ];
    println!(
        "| bus | frames per period | bus time per period | max loop rate (100 %) | at 70 % | 20 kHz load |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, messages, rates) in configs {
        let per_period: Vec<Traffic> = messages.iter().map(|m| Traffic::message(m, 1.0)).collect();
        let busy_s = BusLoad::of(&per_period, rates).load;
        let at_20k: Vec<Traffic> = messages
            .iter()
            .map(|m| Traffic::message(m, 20_000.0))
            .collect();
        let load = BusLoad::of(&at_20k, rates);
        let names: Vec<&str> = messages.iter().map(|m| m.name).collect();
        println!(
            "| {name} | {} | {:.1} us | {:.0} Hz | {:.0} Hz | {:.0} % ({}) |",
            names.join(" + "),
            busy_s * 1e6,
            1.0 / busy_s,
            LoadLimits::DEFAULT.warn / busy_s,
            load.load * 100.0,
            match load.check(LoadLimits::DEFAULT) {
                Ok(None) => "fits",
                Ok(Some(_)) => "warn",
                Err(_) => "refused",
            }
        );
    }
}
