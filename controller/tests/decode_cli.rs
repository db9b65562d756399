//! `scanhil decode` on a technician's own capture: `candump -L -x -e -8 -d can0` lines, as
//! can-utils writes them (the fixture's lines follow `snprintf_canframe` in can-utils' lib.c
//! and the log branch of candump.c: ` R`/` T` direction, `CAN_ERR_FLAG` ids, the `_N` raw
//! DLC, the `DROPCOUNT` notice).

use std::path::Path;
use std::process::Command;

#[test]
fn a_technicians_capture_decodes_every_frame_and_counts_the_error_frames() {
    let log =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/recordings/candump-technician.log");
    let out = Command::new(env!("CARGO_BIN_EXE_scanhil"))
        .args(["decode", "--format", "candump"])
        .arg(&log)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    let frames: Vec<_> = lines
        .iter()
        .filter(|l| l.get("message").is_some())
        .collect();
    let errors: Vec<_> = lines
        .iter()
        .filter(|l| l.get("error_frame").is_some())
        .collect();
    assert_eq!(frames.len(), 7, "every data frame decodes: {lines:?}");
    assert_eq!(errors.len(), 3, "{lines:?}");
    assert_eq!(
        frames
            .iter()
            .map(|f| f["message"].as_str().unwrap())
            .collect::<Vec<_>>(),
        [
            "StatusController",
            "CoilCommand",
            "Step",
            "AngleReading",
            "Distance",
            "CoilCommand",
            "Step"
        ]
    );
    assert_eq!(frames[0]["direction"], "R");
    assert_eq!(frames[1]["direction"], "T");
    assert_eq!(frames[5]["len8_dlc"], 15);
    assert!(frames[4].get("len8_dlc").is_none());
    assert_eq!(
        errors[0]["error_frame"],
        serde_json::json!(["protocol_violation", "bus_error"])
    );
    assert_eq!(
        errors[1]["error_frame"],
        serde_json::json!(["controller", "error_counters"])
    );
    assert_eq!(errors[1]["data"], "0004000000006000");
    assert_eq!(errors[2]["error_frame"], serde_json::json!(["bus_off"]));
    assert_eq!(errors[2]["id"], 0x2000_0040);
    assert!(stderr.contains("3 error frame(s)"), "{stderr}");
    assert!(
        stderr.contains("2 frame(s) dropped by the logging socket"),
        "{stderr}"
    );
    assert!(!stderr.contains("malformed"), "{stderr}");
}
