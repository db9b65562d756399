//! `scanhil-fuzz-afl TARGET`: one fuzz target under AFL++ (persistent mode), for
//! `cargo afl fuzz`. Build with `cargo afl build --release -p scanhil-fuzz --features afl`;
//! the commands of a run are in docs/testing.md (Fuzzing).

use std::process::ExitCode;

fn main() -> ExitCode {
    let name = std::env::args().nth(1).unwrap_or_default();
    let Some(target) = scanhil_fuzz::target(&name) else {
        let names: Vec<&str> = scanhil_fuzz::TARGETS.iter().map(|t| t.name).collect();
        eprintln!(
            "usage: scanhil-fuzz-afl TARGET (one of {})",
            names.join(", ")
        );
        return ExitCode::from(2);
    };
    let run = target.run;
    afl::fuzz!(|data: &[u8]| run(data));
    ExitCode::SUCCESS
}
