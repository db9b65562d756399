//! Linux network interface names (`can0`, `vcan0`), as the kernel accepts them
//! (`dev_valid_name` in net/core/dev.c): not empty, at most 15 bytes (`IFNAMSIZ` - 1), not `.`
//! or `..`, no `/`, `:` or white space. A `socketcan:` URI and a recording's interface name
//! (`--record-iface`) are held to the same rule.

/// The longest interface name, in bytes (`IFNAMSIZ` - 1).
pub const MAX_LEN: usize = 15;

/// Why a name cannot be a Linux interface name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InterfaceNameError {
    /// An empty name.
    #[error("an interface name cannot be empty")]
    Empty,
    /// Longer than [`MAX_LEN`] bytes.
    #[error("interface name `{name}` is {len} bytes, longer than {MAX_LEN}")]
    TooLong {
        /// The name.
        name: String,
        /// Its length in bytes.
        len: usize,
    },
    /// `.` or `..`.
    #[error("`{0}` is not an interface name (`.` and `..` are reserved)")]
    Reserved(String),
    /// A `/`, `:` or white-space byte at `offset`.
    #[error(
        "interface name `{name}` contains {byte:?} at byte {offset} (no `/`, `:` or white space)"
    )]
    BadByte {
        /// The name.
        name: String,
        /// The byte, as a character.
        byte: char,
        /// Its byte offset in the name.
        offset: usize,
    },
}

/// Checks `name` against the kernel's rule.
///
/// # Errors
/// [`InterfaceNameError`] saying which part of the rule it breaks.
pub fn check(name: &str) -> Result<(), InterfaceNameError> {
    if name.is_empty() {
        return Err(InterfaceNameError::Empty);
    }
    if name.len() > MAX_LEN {
        return Err(InterfaceNameError::TooLong {
            name: name.to_owned(),
            len: name.len(),
        });
    }
    if name == "." || name == ".." {
        return Err(InterfaceNameError::Reserved(name.to_owned()));
    }
    match name.bytes().position(is_forbidden) {
        Some(offset) => Err(InterfaceNameError::BadByte {
            name: name.to_owned(),
            byte: char::from(name.as_bytes()[offset]),
            offset,
        }),
        None => Ok(()),
    }
}

/// `/`, `:`, or white space as the kernel's `isspace` has it (space, `\t` `\n` `\v` `\f` `\r`).
fn is_forbidden(byte: u8) -> bool {
    matches!(byte, b'/' | b':' | b' ' | b'\t'..=b'\r')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernels_rule_is_held() {
        for good in [
            "can0",
            "vcan0",
            "fsm",
            "a",
            "can_bus-1.2",
            "fifteen_bytes_x",
        ] {
            assert_eq!(check(good), Ok(()), "{good}");
        }
        assert_eq!(check(""), Err(InterfaceNameError::Empty));
        assert_eq!(
            check("sixteen_bytes_xx"),
            Err(InterfaceNameError::TooLong {
                name: "sixteen_bytes_xx".into(),
                len: 16
            })
        );
        for reserved in [".", ".."] {
            assert_eq!(
                check(reserved),
                Err(InterfaceNameError::Reserved(reserved.into()))
            );
        }
        assert_eq!(check("..."), Ok(()));
        for (bad, byte, offset) in [
            ("can/0", '/', 3),
            ("can0:1", ':', 4),
            ("can 0", ' ', 3),
            ("\tcan0", '\t', 0),
            ("can0\n", '\n', 4),
            ("ca\x0bn", '\x0b', 2),
            ("ca\x0cn", '\x0c', 2),
            ("can\r", '\r', 3),
        ] {
            assert_eq!(
                check(bad),
                Err(InterfaceNameError::BadByte {
                    name: bad.into(),
                    byte,
                    offset
                }),
                "{bad:?}"
            );
        }
        // Bytes beside the forbidden ones pass.
        for near in ["can\x08", "can\x0e", "can.", "can;", "can9"] {
            assert_eq!(check(near), Ok(()), "{near:?}");
        }
    }

    #[test]
    fn messages_name_the_value_and_the_rule() {
        let long = check("a_name_of_twenty_bytes").unwrap_err().to_string();
        assert!(long.contains("22 bytes, longer than 15"), "{long}");
        let slash = check("can/0").unwrap_err().to_string();
        assert!(slash.contains("'/' at byte 3"), "{slash}");
    }
}
