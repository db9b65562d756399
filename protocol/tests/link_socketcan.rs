//! SocketCAN links on a host that may have no kernel CAN: opening fails with an error that
//! names the link and the reason, never a panic. (The frame tests over a live vcan0 are in
//! link_socketcan_vcan.rs, feature `vcan`.)

use std::path::Path;

use scanhil_protocol::link::{CanLink, LinkError, LinkUri, Role};

#[tokio::test]
async fn opening_a_missing_interface_names_it_and_says_what_to_do() {
    let uri: LinkUri = "socketcan:nosuchcan7".parse().unwrap();
    let error = CanLink::open(&uri, Role::Host).await.unwrap_err();
    assert!(matches!(error, LinkError::Open { .. }), "{error}");
    let text = error.to_string();
    assert!(
        text.starts_with("cannot open socketcan:nosuchcan7: "),
        "{text}"
    );
    assert!(text.contains("No such device"), "{text}");
    assert!(
        text.contains("ip link add dev nosuchcan7 type vcan"),
        "{text}"
    );
}

/// On this project's machines the kernel has no CAN and there is no vcan0: opening it must
/// fail cleanly. Where vcan0 exists (inside ci/vcan-vm.sh, a developer's box) it must open.
#[tokio::test]
async fn opening_socketcan_vcan0_fails_clearly_where_there_is_no_vcan0() {
    let uri: LinkUri = "socketcan:vcan0".parse().unwrap();
    let result = CanLink::open(&uri, Role::Device).await;
    if Path::new("/sys/class/net/vcan0").exists() {
        let link = result.expect("vcan0 exists, so socketcan:vcan0 must open");
        assert_eq!(link.name(), "socketcan:vcan0");
    } else {
        let text = result.unwrap_err().to_string();
        assert!(text.starts_with("cannot open socketcan:vcan0: "), "{text}");
        assert!(text.contains("(os error"), "{text}");
        assert!(text.contains("modprobe"), "{text}");
    }
}

#[tokio::test]
async fn an_ild_uri_is_not_a_can_link() {
    let uri: LinkUri = "ild:/dev/ttyUSB0".parse().unwrap();
    let text = CanLink::open(&uri, Role::Host)
        .await
        .unwrap_err()
        .to_string();
    assert!(text.contains("ild:/dev/ttyUSB0@691200"), "{text}");
    assert!(text.contains("use socketcan: or slcan:"), "{text}");
}
