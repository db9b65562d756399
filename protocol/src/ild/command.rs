//! The ILD 2300's ASCII command subset, both ends: the host encodes [`IldCommand`]s and
//! parses [`IldReply`]s with [`IldReplyParser`]; the device (the emulator's sensor node)
//! parses command lines with [`IldCommand::parse`] and answers with [`IldReply::encode`].
//!
//! A command is one line ending in CR. The reply repeats the command with its parameters
//! (when `ECHO ON`), then any information lines, an `Exx <text>` error or `Wxx <text>`
//! warning line, and ends with the prompt `->`. Lines in replies end with CR LF.
//!
//! Checked against the manual: the command names, `ECHO ON|OFF`, the measuring rates, the
//! `->` prompt and the `Exx`/`Wxx` shape (e.g. `E32 Timeout`). Unchecked, so kept in the
//! named constants below: the parameter words of `OUTPUT`, `OUTDIST_RS422`, `OUTADD_RS422`,
//! the baud rate list, the error numbers other than 32, the laser-power command
//! ([`LASER_POWER_COMMAND_UNCHECKED`], not in our notes of the manual), and the form of a
//! query's answer ([`IldReply::query_answer`]).

use std::fmt::Write;

/// The prompt that ends every reply.
pub const PROMPT: &str = "->";
/// Line end inside replies.
pub const REPLY_EOL: &str = "\r\n";
/// The measuring rates `MEASRATE` accepts, in kHz (checked).
pub const MEASURING_RATES_KHZ: [f64; 7] = [1.5, 2.5, 5.0, 10.0, 20.0, 30.0, 49.14];
/// The baud rates `BAUDRATE` accepts (UNCHECKED: the family's usual list).
pub const BAUD_RATES_UNCHECKED: [u32; 6] = [9_600, 115_200, 230_400, 460_800, 691_200, 921_600];
/// The parameter words of `OUTPUT` (UNCHECKED).
pub const OUTPUT_WORDS_UNCHECKED: [&str; 3] = ["NONE", "RS422", "ANALOG"];
/// The parameter words of `OUTDIST_RS422`: off / on (UNCHECKED).
pub const OUTDIST_WORDS_UNCHECKED: [&str; 2] = ["NONE", "DIST1"];
/// The parameter words of `OUTADD_RS422`, in the order of [`AddValue`] (UNCHECKED).
pub const OUTADD_WORDS_UNCHECKED: [&str; 6] = [
    "SHUTTER",
    "COUNTER",
    "TIMESTAMP",
    "TEMP",
    "INTENSITY",
    "STATE",
];
/// The command that switches the laser on and off (UNCHECKED: not in our notes of the ILD 2300
/// manual; the name the optoNCDT family uses).
pub const LASER_POWER_COMMAND_UNCHECKED: &str = "LASERPOW";
/// The parameter words of [`LASER_POWER_COMMAND_UNCHECKED`]: off / on at full power
/// (UNCHECKED).
pub const LASER_POWER_WORDS_UNCHECKED: [&str; 2] = ["OFF", "FULL"];
/// Error number and text for an unknown command (UNCHECKED number).
pub const ERROR_UNKNOWN_COMMAND: (u8, &str) = (1, "Unknown command");
/// Error number and text for a wrong parameter (UNCHECKED number).
pub const ERROR_WRONG_PARAMETER: (u8, &str) = (4, "Wrong parameter");
/// Error number and text for a timeout (checked: `E32 Timeout`).
pub const ERROR_TIMEOUT: (u8, &str) = (32, "Timeout");

/// An extra value per output cycle (`OUTADD_RS422`), sent after the distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AddValue {
    /// Exposure time.
    Shutter,
    /// The 18-bit measured-value counter.
    Counter,
    /// Timestamp (0.25 ms units).
    Timestamp,
    /// Temperature (0.25 degC units).
    Temperature,
    /// Intensity.
    Intensity,
    /// State.
    State,
}

impl AddValue {
    const ALL: [AddValue; 6] = [
        AddValue::Shutter,
        AddValue::Counter,
        AddValue::Timestamp,
        AddValue::Temperature,
        AddValue::Intensity,
        AddValue::State,
    ];

    /// The parameter word.
    #[must_use]
    pub fn word(self) -> &'static str {
        OUTADD_WORDS_UNCHECKED[Self::ALL.iter().position(|&v| v == self).unwrap_or(0)]
    }

    fn from_word(word: &str) -> Option<AddValue> {
        OUTADD_WORDS_UNCHECKED
            .iter()
            .position(|w| w.eq_ignore_ascii_case(word))
            .map(|i| Self::ALL[i])
    }
}

/// A command of the subset. `None` parameters are queries.
#[derive(Debug, Clone, PartialEq)]
pub enum IldCommand {
    /// `GETINFO`: name, serial, measuring range, version.
    GetInfo,
    /// `MEASRATE [kHz]`.
    MeasRate(Option<f64>),
    /// `ECHO [ON|OFF]`.
    Echo(Option<bool>),
    /// `OUTDIST_RS422 [NONE|DIST1]`: the distance on RS422 off / on.
    OutDistRs422(Option<bool>),
    /// `OUTADD_RS422 [NONE|<value> ...]`: extra values per cycle (empty list = NONE).
    OutAddRs422(Option<Vec<AddValue>>),
    /// `BAUDRATE [baud]`.
    Baudrate(Option<u32>),
    /// `OUTPUT [NONE|RS422|ANALOG]`: which interface outputs measured values.
    Output(Option<String>),
    /// `LASERPOW [OFF|FULL]`: the laser off / on ([`LASER_POWER_COMMAND_UNCHECKED`]).
    LaserPower(Option<bool>),
}

/// Why a command line was refused (the device answers with the error's `Exx` line).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IldCommandError {
    /// Not a command of the subset.
    #[error("unknown command {0:?}")]
    UnknownCommand(String),
    /// A parameter the command does not take.
    #[error("{command}: wrong parameter {parameter:?}")]
    WrongParameter {
        /// The command name.
        command: &'static str,
        /// The refused parameter text.
        parameter: String,
    },
}

impl IldCommandError {
    /// The error number and text of the device's `Exx` reply.
    #[must_use]
    pub fn reply_code(&self) -> (u8, &'static str) {
        match self {
            IldCommandError::UnknownCommand(_) => ERROR_UNKNOWN_COMMAND,
            IldCommandError::WrongParameter { .. } => ERROR_WRONG_PARAMETER,
        }
    }
}

impl IldCommand {
    /// The command's name on the line.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            IldCommand::GetInfo => "GETINFO",
            IldCommand::MeasRate(_) => "MEASRATE",
            IldCommand::Echo(_) => "ECHO",
            IldCommand::OutDistRs422(_) => "OUTDIST_RS422",
            IldCommand::OutAddRs422(_) => "OUTADD_RS422",
            IldCommand::Baudrate(_) => "BAUDRATE",
            IldCommand::Output(_) => "OUTPUT",
            IldCommand::LaserPower(_) => LASER_POWER_COMMAND_UNCHECKED,
        }
    }

    /// The parameters as they appear on the line (empty for a query).
    #[must_use]
    pub fn parameters(&self) -> String {
        let on_off = |on: bool, words: [&str; 2]| words[usize::from(on)].to_owned();
        match self {
            IldCommand::GetInfo => String::new(),
            IldCommand::MeasRate(rate) => rate.map(format_khz).unwrap_or_default(),
            IldCommand::Echo(on) => on.map(|on| on_off(on, ["OFF", "ON"])).unwrap_or_default(),
            IldCommand::OutDistRs422(on) => on
                .map(|on| on_off(on, OUTDIST_WORDS_UNCHECKED))
                .unwrap_or_default(),
            IldCommand::OutAddRs422(values) => match values.as_deref() {
                None => String::new(),
                Some([]) => "NONE".to_owned(),
                Some(values) => values
                    .iter()
                    .map(|v| v.word())
                    .collect::<Vec<_>>()
                    .join(" "),
            },
            IldCommand::Baudrate(baud) => baud.map(|b| b.to_string()).unwrap_or_default(),
            IldCommand::Output(word) => word.clone().unwrap_or_default(),
            IldCommand::LaserPower(on) => on
                .map(|on| on_off(on, LASER_POWER_WORDS_UNCHECKED))
                .unwrap_or_default(),
        }
    }

    /// Whether this is a query (no parameters: the device answers the current setting).
    #[must_use]
    pub fn is_query(&self) -> bool {
        self.parameters().is_empty() && *self != IldCommand::GetInfo
    }

    /// The command line with its CR, e.g. `MEASRATE 20\r`.
    #[must_use]
    pub fn encode(&self) -> String {
        let mut line = self.name().to_owned();
        let parameters = self.parameters();
        if !parameters.is_empty() {
            line.push(' ');
            line.push_str(&parameters);
        }
        line.push('\r');
        line
    }

    /// Parses one command line (CR / LF and surrounding blanks ignored, names in any case).
    ///
    /// # Errors
    /// [`IldCommandError`] for an unknown command or a parameter it does not take.
    pub fn parse(line: &str) -> Result<IldCommand, IldCommandError> {
        let mut words = line.split_ascii_whitespace();
        let name = words.next().unwrap_or("").to_ascii_uppercase();
        let params: Vec<&str> = words.collect();
        let wrong = |command: &'static str| IldCommandError::WrongParameter {
            command,
            parameter: params.join(" "),
        };
        let single = |command: &'static str| -> Result<Option<&str>, IldCommandError> {
            match params.as_slice() {
                [] => Ok(None),
                [one] => Ok(Some(*one)),
                _ => Err(wrong(command)),
            }
        };
        let word_index = |command: &'static str, words: &[&str]| -> Result<Option<usize>, _> {
            single(command)?
                .map(|p| {
                    words
                        .iter()
                        .position(|w| w.eq_ignore_ascii_case(p))
                        .ok_or_else(|| wrong(command))
                })
                .transpose()
        };
        Ok(match name.as_str() {
            "GETINFO" if params.is_empty() => IldCommand::GetInfo,
            "GETINFO" => return Err(wrong("GETINFO")),
            "MEASRATE" => IldCommand::MeasRate(
                single("MEASRATE")?
                    .map(|p| {
                        p.parse::<f64>()
                            .ok()
                            .and_then(|khz| {
                                MEASURING_RATES_KHZ
                                    .into_iter()
                                    .find(|r| (r - khz).abs() < 1e-6)
                            })
                            .ok_or_else(|| wrong("MEASRATE"))
                    })
                    .transpose()?,
            ),
            "ECHO" => IldCommand::Echo(word_index("ECHO", &["OFF", "ON"])?.map(|i| i == 1)),
            "OUTDIST_RS422" => IldCommand::OutDistRs422(
                word_index("OUTDIST_RS422", &OUTDIST_WORDS_UNCHECKED)?.map(|i| i == 1),
            ),
            "OUTADD_RS422" => IldCommand::OutAddRs422(match params.as_slice() {
                [] => None,
                [none] if none.eq_ignore_ascii_case("NONE") => Some(Vec::new()),
                words => Some(
                    words
                        .iter()
                        .map(|w| AddValue::from_word(w).ok_or_else(|| wrong("OUTADD_RS422")))
                        .collect::<Result<_, _>>()?,
                ),
            }),
            "BAUDRATE" => IldCommand::Baudrate(
                single("BAUDRATE")?
                    .map(|p| {
                        p.parse::<u32>()
                            .ok()
                            .filter(|b| BAUD_RATES_UNCHECKED.contains(b))
                            .ok_or_else(|| wrong("BAUDRATE"))
                    })
                    .transpose()?,
            ),
            LASER_POWER_COMMAND_UNCHECKED => IldCommand::LaserPower(
                word_index(LASER_POWER_COMMAND_UNCHECKED, &LASER_POWER_WORDS_UNCHECKED)?
                    .map(|i| i == 1),
            ),
            "OUTPUT" => IldCommand::Output(
                word_index("OUTPUT", &OUTPUT_WORDS_UNCHECKED)?
                    .map(|i| OUTPUT_WORDS_UNCHECKED[i].to_owned()),
            ),
            _ => {
                return Err(IldCommandError::UnknownCommand(
                    line.trim_matches(|c: char| c.is_ascii_whitespace())
                        .to_owned(),
                ));
            }
        })
    }
}

/// A rate in kHz as the device writes it (`20`, `2.5`, `49.14`).
fn format_khz(khz: f64) -> String {
    let text = format!("{khz:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// An `Exx` error or `Wxx` warning line of a reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplyCode {
    /// The number `xx`.
    pub code: u8,
    /// The text after it.
    pub text: String,
}

/// One reply, up to and including the `->` prompt.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct IldReply {
    /// The repeated command line (`MEASRATE 20`), when echo is on.
    pub echo: Option<String>,
    /// Information lines (`Name: ILD2300`, ...).
    pub lines: Vec<String>,
    /// Warnings (the command was still done).
    pub warnings: Vec<ReplyCode>,
    /// The error, if the command was refused.
    pub error: Option<ReplyCode>,
}

impl IldReply {
    /// The reply to a refused command line.
    #[must_use]
    pub fn refusal(echo: Option<String>, error: &IldCommandError) -> IldReply {
        let (code, text) = error.reply_code();
        IldReply {
            echo,
            error: Some(ReplyCode {
                code,
                text: text.to_owned(),
            }),
            ..IldReply::default()
        }
    }

    /// The reply's bytes: echo, lines, warnings and error each ending in CR LF, then `->`.
    #[must_use]
    pub fn encode(&self) -> String {
        let mut out = String::new();
        if let Some(echo) = &self.echo {
            out.push_str(echo);
            out.push_str(REPLY_EOL);
        }
        for line in &self.lines {
            out.push_str(line);
            out.push_str(REPLY_EOL);
        }
        for (letter, code) in self
            .warnings
            .iter()
            .map(|w| ('W', w))
            .chain(self.error.iter().map(|e| ('E', e)))
        {
            let _ = write!(out, "{letter}{:02} {}{REPLY_EOL}", code.code, code.text);
        }
        out.push_str(PROMPT);
        out
    }

    /// The device's answer to a query (`MEASRATE` without a parameter): one information line
    /// that is the command with its current setting, e.g. `MEASRATE 20`, which the host reads
    /// back with [`IldReply::queried`]. (UNCHECKED: the manual says a reply repeats the
    /// command with its parameters; that a query's setting comes back in this form is our
    /// reading.)
    #[must_use]
    pub fn query_answer(echo: Option<String>, setting: &IldCommand) -> IldReply {
        IldReply {
            echo,
            lines: vec![setting.encode().trim_end().to_owned()],
            ..IldReply::default()
        }
    }

    /// Host: the setting a query's reply carries: the first information line that parses as
    /// a command named `name` with a parameter (see [`IldReply::query_answer`]).
    #[must_use]
    pub fn queried(&self, name: &str) -> Option<IldCommand> {
        self.lines.iter().find_map(|line| {
            IldCommand::parse(line)
                .ok()
                .filter(|c| c.name() == name && !c.is_query())
        })
    }

    /// True when the command was not refused.
    #[must_use]
    pub fn is_ok(&self) -> bool {
        self.error.is_none()
    }
}

/// The longest reply text kept before the prompt; anything longer is cut (a reply of the
/// subset is a few hundred bytes at most).
pub const MAX_REPLY_LEN: usize = 4096;

/// Host-side incremental reply parser: push bytes, get whole replies at each `->`.
#[derive(Debug, Clone)]
pub struct IldReplyParser {
    echo: bool,
    text: Vec<u8>,
}

impl IldReplyParser {
    /// A parser; `echo` says whether the device repeats commands (`ECHO ON`).
    #[must_use]
    pub fn new(echo: bool) -> IldReplyParser {
        IldReplyParser {
            echo,
            text: Vec::new(),
        }
    }

    /// Feeds `bytes`; returns the replies they complete.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<IldReply> {
        let mut replies = Vec::new();
        for &byte in bytes {
            if self.text.len() < MAX_REPLY_LEN {
                self.text.push(byte);
            }
            if self.text.ends_with(PROMPT.as_bytes()) {
                let body_len = self.text.len() - PROMPT.len();
                let body = String::from_utf8_lossy(&self.text[..body_len]).into_owned();
                replies.push(parse_reply(&body, self.echo));
                self.text.clear();
            }
        }
        replies
    }
}

/// Splits a reply body (text before the prompt) into its parts.
fn parse_reply(body: &str, echo: bool) -> IldReply {
    let mut reply = IldReply::default();
    let mut lines = body
        .split(['\r', '\n'])
        .map(str::trim)
        .filter(|l| !l.is_empty());
    if echo {
        reply.echo = lines.next().map(str::to_owned);
    }
    for line in lines {
        match reply_code(line) {
            Some(('E', code)) => reply.error = Some(code),
            Some((_, code)) => reply.warnings.push(code),
            None => reply.lines.push(line.to_owned()),
        }
    }
    reply
}

/// `Exx text` / `Wxx text` into its letter and code.
fn reply_code(line: &str) -> Option<(char, ReplyCode)> {
    let letter = line.chars().next().filter(|c| matches!(c, 'E' | 'W'))?;
    let digits = line.get(1..3)?;
    if !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let rest = line.get(3..)?;
    if !(rest.is_empty() || rest.starts_with(' ')) {
        return None;
    }
    Some((
        letter,
        ReplyCode {
            code: digits.parse().ok()?,
            text: rest.trim().to_owned(),
        },
    ))
}

/// What `GETINFO` reports: the device's identity and measuring range, as
/// `Key: value` lines (`Name: ILD2300`, `Measuring range: 100.00mm`, ...).
#[derive(Debug, Clone, PartialEq)]
pub struct IldInfo {
    /// `Name` (`ILD2300`).
    pub name: String,
    /// `Serial`.
    pub serial: String,
    /// `Article` (the article number).
    pub article: String,
    /// `Measuring range` in mm (the span, MR).
    pub measuring_range_mm: f64,
    /// `Version` (firmware).
    pub version: String,
}

/// Why a `GETINFO` reply could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IldInfoError {
    /// The device answered with an error.
    #[error("GETINFO refused: E{code:02} {text}")]
    Refused {
        /// The error number.
        code: u8,
        /// Its text.
        text: String,
    },
    /// No `Measuring range:` line.
    #[error("GETINFO reply has no `Measuring range:` line")]
    NoMeasuringRange,
    /// A measuring range that is not `<number>mm` with a finite positive number.
    #[error("GETINFO measuring range {0:?} is not `<number>mm` with a positive number")]
    BadMeasuringRange(String),
}

impl IldInfo {
    /// The reply lines a device sends for `GETINFO` (without echo and prompt).
    #[must_use]
    pub fn reply_lines(&self) -> Vec<String> {
        vec![
            format!("Name: {}", self.name),
            format!("Serial: {}", self.serial),
            format!("Article: {}", self.article),
            format!("Measuring range: {:.2}mm", self.measuring_range_mm),
            format!("Version: {}", self.version),
        ]
    }

    /// Reads a `GETINFO` reply (host side); unknown keys (Option, MAC-Address, ...) are
    /// ignored, missing ones left empty.
    ///
    /// # Errors
    /// [`IldInfoError`]: the device refused, or the measuring range is missing or unreadable.
    pub fn from_reply(reply: &IldReply) -> Result<IldInfo, IldInfoError> {
        if let Some(error) = &reply.error {
            return Err(IldInfoError::Refused {
                code: error.code,
                text: error.text.clone(),
            });
        }
        let value = |key: &str| {
            reply.lines.iter().find_map(|line| {
                let (k, v) = line.split_once(':')?;
                (k.trim().eq_ignore_ascii_case(key)).then(|| v.trim().to_owned())
            })
        };
        let range_text = value("Measuring range").ok_or(IldInfoError::NoMeasuringRange)?;
        // A span the host compares with its rig: `NaN`, `inf` and `-100` parse as numbers, but
        // a NaN span would pass any tolerance check, so only a finite positive span is one.
        let measuring_range_mm = range_text
            .trim_end_matches("mm")
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|mm| mm.is_finite() && *mm > 0.0)
            .ok_or_else(|| IldInfoError::BadMeasuringRange(range_text.clone()))?;
        Ok(IldInfo {
            name: value("Name").unwrap_or_default(),
            serial: value("Serial").unwrap_or_default(),
            article: value("Article").unwrap_or_default(),
            measuring_range_mm,
            version: value("Version").unwrap_or_default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_encode_and_parse_back() {
        let commands = [
            IldCommand::GetInfo,
            IldCommand::MeasRate(Some(49.14)),
            IldCommand::MeasRate(None),
            IldCommand::Echo(Some(false)),
            IldCommand::OutDistRs422(Some(true)),
            IldCommand::OutAddRs422(Some(vec![AddValue::Counter, AddValue::Timestamp])),
            IldCommand::OutAddRs422(Some(vec![])),
            IldCommand::Baudrate(Some(691_200)),
            IldCommand::Output(Some("RS422".to_owned())),
            IldCommand::LaserPower(Some(false)),
            IldCommand::LaserPower(Some(true)),
            IldCommand::LaserPower(None),
        ];
        for command in commands {
            let line = command.encode();
            assert!(line.ends_with('\r'));
            assert_eq!(IldCommand::parse(&line), Ok(command), "{line:?}");
        }
        assert_eq!(IldCommand::MeasRate(Some(20.0)).encode(), "MEASRATE 20\r");
        assert_eq!(
            IldCommand::LaserPower(Some(true)).encode(),
            "LASERPOW FULL\r"
        );
    }

    #[test]
    fn a_query_answer_carries_the_setting_back() {
        let answer = IldReply::query_answer(None, &IldCommand::MeasRate(Some(2.5)));
        assert_eq!(answer.encode(), "MEASRATE 2.5\r\n->");
        let parsed = IldReplyParser::new(false).push(answer.encode().as_bytes());
        assert_eq!(
            parsed[0].queried("MEASRATE"),
            Some(IldCommand::MeasRate(Some(2.5)))
        );
        assert_eq!(parsed[0].queried("BAUDRATE"), None);
        assert!(IldCommand::MeasRate(None).is_query());
        assert!(!IldCommand::GetInfo.is_query());
    }

    #[test]
    fn getinfo_reply_carries_the_measuring_range() {
        let info = IldInfo {
            name: "ILD2300".to_owned(),
            serial: "1234".to_owned(),
            article: "4120xxx".to_owned(),
            measuring_range_mm: 100.0,
            version: "emulated".to_owned(),
        };
        let mut lines = info.reply_lines();
        lines.insert(2, "MAC-Address: 00-0C-12-01-02-03".to_owned());
        let reply = IldReply {
            echo: Some("GETINFO".to_owned()),
            lines,
            ..IldReply::default()
        };
        let parsed = IldReplyParser::new(true).push(reply.encode().as_bytes());
        assert_eq!(IldInfo::from_reply(&parsed[0]), Ok(info));
        assert!(reply.encode().contains("\r\nMeasuring range: 100.00mm\r\n"));
        let no_range = IldReply::default();
        assert_eq!(
            IldInfo::from_reply(&no_range),
            Err(IldInfoError::NoMeasuringRange)
        );
        for span in ["NaN", "inf", "-100", "0"] {
            let odd = IldReply {
                lines: vec![format!("Measuring range: {span}mm")],
                ..IldReply::default()
            };
            assert_eq!(
                IldInfo::from_reply(&odd),
                Err(IldInfoError::BadMeasuringRange(format!("{span}mm"))),
                "{span}"
            );
        }
    }

    #[test]
    fn bad_lines_get_their_error_codes() {
        let unknown = IldCommand::parse("FOO 1").unwrap_err();
        assert_eq!(unknown.reply_code(), ERROR_UNKNOWN_COMMAND);
        let wrong = IldCommand::parse("MEASRATE 7").unwrap_err();
        assert_eq!(
            wrong,
            IldCommandError::WrongParameter {
                command: "MEASRATE",
                parameter: "7".to_owned()
            }
        );
        assert!(IldCommand::parse("ECHO MAYBE").is_err());
        assert!(IldCommand::parse("BAUDRATE 12345").is_err());
    }

    #[test]
    fn replies_round_trip_through_the_host_parser() {
        let info = IldReply {
            echo: Some("GETINFO".to_owned()),
            lines: vec!["Name: ILD2300".into(), "Measuring range: 100.00mm".into()],
            ..IldReply::default()
        };
        let refusal = IldReply::refusal(
            Some("MEASRATE 7".to_owned()),
            &IldCommand::parse("MEASRATE 7").unwrap_err(),
        );
        let text = info.encode() + &refusal.encode();
        let mut parser = IldReplyParser::new(true);
        // Byte by byte, as a serial line delivers it.
        let replies: Vec<_> = text.bytes().flat_map(|b| parser.push(&[b])).collect();
        assert_eq!(replies, vec![info, refusal.clone()]);
        assert_eq!(refusal.encode(), "MEASRATE 7\r\nE04 Wrong parameter\r\n->");
    }
}
