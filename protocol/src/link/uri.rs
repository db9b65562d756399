//! Link URIs as given on the command line: `socketcan:IFACE[@BITRATE]`,
//! `slcan:PATH[@BITRATE][?family=FAMILY]` and `ild:PATH[@BAUD]`.
//!
//! Bit rates and baud rates accept a plain integer or a `k`/`M` suffix (`500k`, `1M`).
//! `@BITRATE` on a SocketCAN interface is not configured by the link (use `ip link`); it tells
//! the bus-load check what the bus runs at, and is checked against the rate the interface
//! reports. On `slcan:` it selects the adapter's `Sn` command from its family's table
//! (`?family=canable` (the default), `lawicel` or `linux`: [`AdapterFamily`]) and is what the
//! bus-load check uses; without it no `Sn` is sent and the adapter keeps its own setting.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use crate::ild::stream::FACTORY_BAUD as ILD_DEFAULT_BAUD;
use crate::interface_name::{self, InterfaceNameError};
use crate::slcan::family::AdapterFamily;

/// The serial baud rate used on an SLCAN line. USB adapters (CANable, ttyACM) and ptys ignore
/// it; a UART adapter needing another rate is reconfigured with `stty` before use.
pub const SLCAN_SERIAL_BAUD: u32 = 115_200;

/// A parsed link URI.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkUri {
    /// A kernel SocketCAN interface (`vcan0`, `can0`).
    SocketCan {
        /// The interface name.
        iface: String,
        /// The bus's bit rate for the bus-load check, if given (not configured by the link).
        bitrate: Option<u32>,
    },
    /// SLCAN (Lawicel) over a serial port or pty.
    Slcan {
        /// The serial device path.
        path: PathBuf,
        /// The CAN bit rate given in the URI (`None`: no `Sn` sent, the adapter keeps its
        /// own setting; no bus-load check).
        bitrate: Option<u32>,
        /// The adapter's family: which `Sn` digit sets which bit rate.
        family: AdapterFamily,
    },
    /// The ILD 2300's RS422 byte stream and ASCII commands over a serial port or pty.
    Ild {
        /// The serial device path.
        path: PathBuf,
        /// The serial baud rate.
        baud: u32,
    },
}

impl LinkUri {
    /// The CAN bit rate to check the bus load against: `Some` only when the URI gave one.
    #[must_use]
    pub fn bus_bitrate(&self) -> Option<u32> {
        match self {
            LinkUri::SocketCan { bitrate, .. } | LinkUri::Slcan { bitrate, .. } => *bitrate,
            LinkUri::Ild { .. } => None,
        }
    }

    /// Whether this link carries CAN frames (`socketcan:` or `slcan:`).
    #[must_use]
    pub fn is_can(&self) -> bool {
        !matches!(self, LinkUri::Ild { .. })
    }
}

impl fmt::Display for LinkUri {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkUri::SocketCan { iface, bitrate } => {
                write!(f, "socketcan:{iface}")?;
                bitrate.map_or(Ok(()), |b| write!(f, "@{b}"))
            }
            LinkUri::Slcan {
                path,
                bitrate,
                family,
            } => {
                write!(f, "slcan:{}", path.display())?;
                bitrate.map_or(Ok(()), |b| write!(f, "@{b}"))?;
                if *family == AdapterFamily::default() {
                    Ok(())
                } else {
                    write!(f, "?family={family}")
                }
            }
            LinkUri::Ild { path, baud } => write!(f, "ild:{}@{baud}", path.display()),
        }
    }
}

/// A link URI that did not parse: the URI, the byte offset of the problem and what it is.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("bad link URI `{uri}` at byte {offset}: {reason}")]
pub struct UriError {
    /// The URI as given.
    pub uri: String,
    /// Byte offset into the URI where the problem starts.
    pub offset: usize,
    /// What is wrong there.
    pub reason: String,
}

impl FromStr for LinkUri {
    type Err = UriError;

    fn from_str(uri: &str) -> Result<Self, UriError> {
        let fail = |offset: usize, reason: String| UriError {
            uri: uri.to_owned(),
            offset,
            reason,
        };
        let Some((scheme, rest)) = uri.split_once(':') else {
            return Err(fail(
                0,
                "expected `socketcan:IFACE`, `slcan:PATH[@BITRATE]` or `ild:PATH[@BAUD]`".into(),
            ));
        };
        let body_at = scheme.len() + 1;
        let (rest, options) = match rest.split_once('?') {
            Some((body, options)) => (body, Some((options, body_at + body.len() + 1))),
            None => (rest, None),
        };
        if let Some((_, at)) = options
            && scheme != "slcan"
        {
            return Err(fail(
                at - 1,
                format!("`{scheme}:` takes no options (`?...` is for `slcan:` only)"),
            ));
        }
        let (target, rate) = match rest.rsplit_once('@') {
            Some((target, rate)) => (target, Some((rate, body_at + target.len() + 1))),
            None => (rest, None),
        };
        if target.is_empty() {
            let what = if scheme == "socketcan" {
                "interface name"
            } else {
                "device path"
            };
            return Err(fail(body_at, format!("missing {what} after `{scheme}:`")));
        }
        let rate_at = rate.map_or(uri.len(), |(_, at)| at);
        let rate = rate
            .map(|(text, at)| parse_rate(text).map_err(|r| fail(at, r)))
            .transpose()?;
        match scheme {
            "socketcan" => {
                if let Err(error) = interface_name::check(target) {
                    let offset = match &error {
                        InterfaceNameError::BadByte { offset, .. } => body_at + offset,
                        _ => body_at,
                    };
                    return Err(fail(offset, error.to_string()));
                }
                Ok(LinkUri::SocketCan {
                    iface: target.to_owned(),
                    bitrate: rate,
                })
            }
            "slcan" => {
                let family = match options {
                    Some((options, at)) => parse_family(options).map_err(|r| fail(at, r))?,
                    None => AdapterFamily::default(),
                };
                if let Some(bitrate) = rate
                    && family.code_for(bitrate).is_none()
                {
                    return Err(fail(rate_at, refusal(family, bitrate)));
                }
                Ok(LinkUri::Slcan {
                    path: PathBuf::from(target),
                    bitrate: rate,
                    family,
                })
            }
            "ild" => Ok(LinkUri::Ild {
                path: PathBuf::from(target),
                baud: rate.unwrap_or(ILD_DEFAULT_BAUD),
            }),
            other => Err(fail(
                0,
                format!("unknown link kind `{other}` (expected `socketcan`, `slcan` or `ild`)"),
            )),
        }
    }
}

/// Parses the options of an `slcan:` URI: `family=NAME`.
fn parse_family(options: &str) -> Result<AdapterFamily, String> {
    match options.split_once('=') {
        Some(("family", name)) => name
            .parse()
            .map_err(|e: crate::slcan::family::UnknownFamily| e.to_string()),
        _ => Err(format!(
            "unknown option `{options}` (the one option is `family=canable|lawicel|linux`)"
        )),
    }
}

/// Why `family` cannot set `bitrate`: its table, and the families that can.
fn refusal(family: AdapterFamily, bitrate: u32) -> String {
    let others: Vec<String> = AdapterFamily::families_setting(bitrate)
        .iter()
        .map(|f| format!("`?family={f}`"))
        .collect();
    let hint = if others.is_empty() {
        String::new()
    } else {
        format!("; {} adapters set it", others.join(" or "))
    };
    format!(
        "CAN bit rate {bitrate} is not one a {family} SLCAN adapter can set ({}){hint}",
        family.table_text()
    )
}

/// Parses `1000000`, `500k`, `1M` into bits (or bauds) per second.
fn parse_rate(text: &str) -> Result<u32, String> {
    let (digits, factor) = match text.strip_suffix(['k', 'K']) {
        Some(d) => (d, 1_000),
        None => match text.strip_suffix('M') {
            Some(d) => (d, 1_000_000),
            None => (text, 1),
        },
    };
    digits
        .parse::<u32>()
        .ok()
        .and_then(|n| n.checked_mul(factor))
        .filter(|&n| n > 0)
        .ok_or_else(|| {
            format!("rate `{text}` is not a positive whole number (e.g. `1000000`, `500k`, `1M`)")
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_each_kind() {
        assert_eq!(
            "socketcan:vcan0".parse::<LinkUri>().unwrap(),
            LinkUri::SocketCan {
                iface: "vcan0".into(),
                bitrate: None
            }
        );
        assert_eq!(
            "slcan:/dev/ttyACM0@500k".parse::<LinkUri>().unwrap(),
            LinkUri::Slcan {
                path: "/dev/ttyACM0".into(),
                bitrate: Some(500_000),
                family: AdapterFamily::Canable,
            }
        );
        assert_eq!(
            "slcan:/dev/ttyUSB0@800k?family=lawicel"
                .parse::<LinkUri>()
                .unwrap(),
            LinkUri::Slcan {
                path: "/dev/ttyUSB0".into(),
                bitrate: Some(800_000),
                family: AdapterFamily::Lawicel,
            }
        );
        assert_eq!(
            "slcan:/dev/ttyACM0?family=linux"
                .parse::<LinkUri>()
                .unwrap(),
            LinkUri::Slcan {
                path: "/dev/ttyACM0".into(),
                bitrate: None,
                family: AdapterFamily::Linux,
            }
        );
        assert_eq!(
            "ild:/dev/ttyUSB0".parse::<LinkUri>().unwrap(),
            LinkUri::Ild {
                path: "/dev/ttyUSB0".into(),
                baud: ILD_DEFAULT_BAUD
            }
        );
        assert_eq!(
            "socketcan:can0@1M"
                .parse::<LinkUri>()
                .unwrap()
                .bus_bitrate(),
            Some(1_000_000)
        );
    }

    #[test]
    fn display_round_trips() {
        for text in [
            "socketcan:can0@1000000",
            "slcan:/dev/pts/3@125000",
            "slcan:/dev/pts/3@800000?family=linux",
            "slcan:/dev/pts/3?family=lawicel",
            "ild:/dev/x@921600",
        ] {
            assert_eq!(text.parse::<LinkUri>().unwrap().to_string(), text);
        }
    }

    #[test]
    fn errors_say_what_and_where() {
        let e = "slcan:/dev/ttyACM0@123456".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 19);
        assert!(e.to_string().contains("123456"), "{e}");
        assert!(e.to_string().contains("canable SLCAN adapter"), "{e}");
        assert!(e.to_string().contains("S0..S9"), "{e}");
        assert!(!e.to_string().contains("family="), "no family sets it: {e}");

        // S7 is 750k on a CANable: 800k is refused there, naming who sets it.
        let e = "slcan:/dev/ttyACM0@800k".parse::<LinkUri>().unwrap_err();
        assert_eq!(
            e.reason,
            "CAN bit rate 800000 is not one a canable SLCAN adapter can set (S0..S9: 10000, \
             20000, 50000, 100000, 125000, 250000, 500000, 750000, 1000000, 83300 bit/s); \
             `?family=lawicel` or `?family=linux` adapters set it"
        );
        let e = "slcan:/dev/ttyUSB0@750k?family=linux"
            .parse::<LinkUri>()
            .unwrap_err();
        assert!(e.reason.contains("`?family=canable`"), "{e}");

        let e = "slcan:/dev/x?family=peak".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 13);
        assert!(
            e.reason.contains("unknown SLCAN adapter family `peak`"),
            "{e}"
        );
        let e = "slcan:/dev/x@1M?speed=fast".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 16);
        assert!(e.reason.contains("unknown option `speed=fast`"), "{e}");
        let e = "socketcan:can0?family=linux"
            .parse::<LinkUri>()
            .unwrap_err();
        assert_eq!(e.offset, 14);
        assert!(e.reason.contains("takes no options"), "{e}");

        let e = "can:vcan0".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 0);
        assert!(e.reason.contains("unknown link kind `can`"), "{e}");

        let e = "ild:/dev/ttyUSB0@fast".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 17);

        let e = "slcan:".parse::<LinkUri>().unwrap_err();
        assert!(e.reason.contains("missing device path"), "{e}");

        let e = "socketcan:averyveryverylongname0"
            .parse::<LinkUri>()
            .unwrap_err();
        assert!(e.reason.contains("longer than 15"), "{e}");

        let e = "vcan0".parse::<LinkUri>().unwrap_err();
        assert_eq!(e.offset, 0);

        let e = "ild:/dev/x@0".parse::<LinkUri>().unwrap_err();
        assert!(e.reason.contains("positive"), "{e}");
    }
}
