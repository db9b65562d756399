//! The ILD 2300's ASCII command subset, both ends: the host encodes [`IldCommand`]s and
//! parses [`IldReply`]s with [`IldReplyParser`]; the device (the emulator's sensor node)
//! parses command lines with [`IldCommand::parse`] and answers with [`IldReply::encode`].
//!
//! As the optoNCDT 2300 operating instructions have it (appendix A 6, "ASCII Communication with
//! Sensor"; `docs/decisions.md` lists each fact with its section and page):
//! - a reply is any information lines, an `Exx <text>` error or `Wxx <text>` warning line, and
//!   the prompt `->` (A 6.1, p. 122); with `ECHO ON` the reply to a command first repeats it,
//!   `<command> ok` for a setting done (A 6.3.1.6, p. 129);
//! - a query (a command without its parameters) is answered with the setting in the form of the
//!   command that sets it (`MEASRATE 20`: "the reply can be used again as command", p. 122);
//! - `MEASRATE 1.5|2.5|5|10|20|30|49` in kHz, the top rate written `49` for its 49.14 kHz
//!   (A 6.4.1.4, p. 136; [`MeasuringRate`]);
//! - `OUTDIST_RS422 NONE|DIST1` (A 6.5.2.2), `OUTADD_RS422 NONE|([TEMP] [SHUTTER] [COUNTER]
//!   [TIMESTAMP] [INTENSITY] [STATE])` (A 6.5.2.5, p. 143), and `GETOUTINFO_RS422`, whose list is
//!   the order of the values on the line (A 6.5.2.1, p. 142; [`IldOutputInfo`]);
//! - the 2300 outputs on RS422 or Ethernet, never both, and has no analog output (chap. 9,
//!   p. 94 and 98): `OUTPUT RS422|ETHERNET`, and `NONE` as the sister ILD 1420 has it.
//!
//! Not in the 2300's manual as found, so kept in named constants and sent in the form that
//! works either way: the command line end ([`COMMAND_EOL`], CR LF: the ILD 1220/1420 manuals
//! require LF and accept CR LF), `OUTPUT NONE`, the baud rate list, the error numbers other
//! than `E32 Timeout`, and the laser-power command ([`LASER_POWER_COMMAND_UNCHECKED`]).

use std::fmt::Write;

/// The prompt that ends every reply.
pub const PROMPT: &str = "->";
/// Line end inside replies.
pub const REPLY_EOL: &str = "\r\n";
/// Line end of a command the host sends: CR LF. The ILD 1220 and 1420 manuals (A 3.1) require
/// LF and accept CR LF, and public drivers of the family send CR LF; the 2300's manual does not
/// say, so CR LF, which works either way.
pub const COMMAND_EOL: &str = "\r\n";
/// What follows the repeated command in a reply when echo is on and a setting was done
/// (`MEASRATE 20 ok`, A 6.3.1.6).
pub const ECHO_DONE_SUFFIX: &str = " ok";
/// The baud rates `BAUDRATE` accepts (UNCHECKED: the family's usual list).
pub const BAUD_RATES_UNCHECKED: [u32; 6] = [9_600, 115_200, 230_400, 460_800, 691_200, 921_600];
/// The parameter words of `OUTPUT`: RS422 and ETHERNET are the 2300's two outputs (chap. 9);
/// NONE (output off) is the ILD 1420's word (its A 3.5.1), not confirmed for the 2300.
pub const OUTPUT_WORDS: [&str; 3] = ["NONE", "RS422", "ETHERNET"];
/// The `OUTPUT` word that puts measured values on RS422.
pub const OUTPUT_RS422: &str = "RS422";
/// The `OUTPUT` word that stops the output ([`OUTPUT_WORDS`]).
pub const OUTPUT_NONE: &str = "NONE";
/// The parameter words of `OUTDIST_RS422`: off / the displacement (A 6.5.2.2; `DIST2` only in
/// thickness measurement, which the subset has not).
pub const OUTDIST_WORDS: [&str; 2] = ["NONE", "DIST1"];
/// The command that switches the laser on and off (UNCHECKED: not in the ILD 2300 manual as
/// found; the name the optoNCDT family uses).
pub const LASER_POWER_COMMAND_UNCHECKED: &str = "LASERPOW";
/// The parameter words of [`LASER_POWER_COMMAND_UNCHECKED`]: off / on at full power
/// (UNCHECKED).
pub const LASER_POWER_WORDS_UNCHECKED: [&str; 2] = ["OFF", "FULL"];
/// Error number and text for an unknown command (UNCHECKED number).
pub const ERROR_UNKNOWN_COMMAND: (u8, &str) = (1, "Unknown command");
/// Error number and text for a wrong parameter (UNCHECKED number).
pub const ERROR_WRONG_PARAMETER: (u8, &str) = (4, "Wrong parameter");
/// Error number and text for a timeout (checked: `E32 Timeout`, A 6.4.4.5).
pub const ERROR_TIMEOUT: (u8, &str) = (32, "Timeout");

/// How the device end takes command lines: any of CR, LF or CR LF ends a line, or only LF does,
/// as the ILD 1220 and 1420 firmwares require (their manuals, A 3.1: "must include LF, but may
/// also be CR LF"). Under [`LineEnding::Lf`] a CR is ignored, so a host ending its commands in
/// CR alone gets no reply.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum LineEnding {
    /// CR, LF or CR LF end a line.
    #[default]
    CrOrLf,
    /// Only LF ends a line; CR is ignored.
    Lf,
}

/// The ILD 2300's measuring rates, as `MEASRATE` words them (A 6.4.1.4, p. 136) and as the
/// sensor measures. The top rate is written `49` and is 49.14 kHz (chap. 9.2, p. 98: "at
/// 49,140 kHz"): the word goes on the wire, the rate into timing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeasuringRate {
    /// 1.5 kHz.
    Khz1_5,
    /// 2.5 kHz.
    Khz2_5,
    /// 5 kHz.
    Khz5,
    /// 10 kHz.
    Khz10,
    /// 20 kHz (the paper's).
    Khz20,
    /// 30 kHz.
    Khz30,
    /// 49.14 kHz, written `49`.
    Khz49,
}

impl MeasuringRate {
    /// Every rate, slowest first.
    pub const ALL: [MeasuringRate; 7] = [
        MeasuringRate::Khz1_5,
        MeasuringRate::Khz2_5,
        MeasuringRate::Khz5,
        MeasuringRate::Khz10,
        MeasuringRate::Khz20,
        MeasuringRate::Khz30,
        MeasuringRate::Khz49,
    ];

    /// The parameter of `MEASRATE` (`1.5`, ..., `49`).
    #[must_use]
    pub fn word(self) -> &'static str {
        match self {
            MeasuringRate::Khz1_5 => "1.5",
            MeasuringRate::Khz2_5 => "2.5",
            MeasuringRate::Khz5 => "5",
            MeasuringRate::Khz10 => "10",
            MeasuringRate::Khz20 => "20",
            MeasuringRate::Khz30 => "30",
            MeasuringRate::Khz49 => "49",
        }
    }

    /// The rate the sensor measures at, Hz (49 140 for the rate written `49`).
    #[must_use]
    pub fn hz(self) -> f64 {
        match self {
            MeasuringRate::Khz1_5 => 1_500.0,
            MeasuringRate::Khz2_5 => 2_500.0,
            MeasuringRate::Khz5 => 5_000.0,
            MeasuringRate::Khz10 => 10_000.0,
            MeasuringRate::Khz20 => 20_000.0,
            MeasuringRate::Khz30 => 30_000.0,
            MeasuringRate::Khz49 => 49_140.0,
        }
    }

    /// The rate measuring at `hz` (within 1 ppm), if the sensor has one.
    #[must_use]
    pub fn from_hz(hz: f64) -> Option<MeasuringRate> {
        Self::ALL
            .into_iter()
            .find(|rate| (rate.hz() - hz).abs() <= 1e-6 * rate.hz())
    }

    /// The rate a `MEASRATE` parameter names: a number equal to one of the words (`20`,
    /// `20.0`, `49`); `49.14` is not one.
    #[must_use]
    pub fn from_word(word: &str) -> Option<MeasuringRate> {
        let khz: f64 = word.parse().ok()?;
        Self::ALL
            .into_iter()
            .find(|rate| rate.word().parse::<f64>().is_ok_and(|w| w == khz))
    }

    /// The rates as the manual lists them, for messages: `1.5|2.5|5|10|20|30|49`.
    #[must_use]
    pub fn words() -> String {
        Self::ALL.map(MeasuringRate::word).join("|")
    }
}

/// An extra value per output cycle (`OUTADD_RS422`), in the order the manual lists them
/// (A 6.5.2.5: TEMP, SHUTTER, COUNTER, TIMESTAMP, INTENSITY, STATE).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AddValue {
    /// Temperature (0.25 degC units).
    Temperature,
    /// Exposure time (12.5 ns units, 17 bits on RS422).
    Shutter,
    /// The 18-bit measured-value counter (wraps at 262 143).
    Counter,
    /// Timestamp (bits 8 to 25 of the microsecond timestamp on RS422: 0.256 ms units).
    Timestamp,
    /// Intensity.
    Intensity,
    /// State.
    State,
}

impl AddValue {
    /// Every extra value, in the manual's order.
    pub const ALL: [AddValue; 6] = [
        AddValue::Temperature,
        AddValue::Shutter,
        AddValue::Counter,
        AddValue::Timestamp,
        AddValue::Intensity,
        AddValue::State,
    ];

    /// The parameter word (`TEMP`, `COUNTER`, ...).
    #[must_use]
    pub fn word(self) -> &'static str {
        match self {
            AddValue::Temperature => "TEMP",
            AddValue::Shutter => "SHUTTER",
            AddValue::Counter => "COUNTER",
            AddValue::Timestamp => "TIMESTAMP",
            AddValue::Intensity => "INTENSITY",
            AddValue::State => "STATE",
        }
    }

    /// The value a word names, in any case.
    #[must_use]
    pub fn from_word(word: &str) -> Option<AddValue> {
        Self::ALL
            .into_iter()
            .find(|value| value.word().eq_ignore_ascii_case(word))
    }
}

/// A set of extra values per cycle, iterated in the manual's order; written in JSON as a list
/// of words in any case (`["counter"]`, `[]` for none).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct AddValueSet(u8);

impl AddValueSet {
    /// No extra value: the distance alone.
    pub const NONE: AddValueSet = AddValueSet(0);

    /// The set holding `values`.
    #[must_use]
    pub fn of(values: &[AddValue]) -> AddValueSet {
        AddValueSet(
            values
                .iter()
                .fold(0, |bits, &value| bits | Self::bit(value)),
        )
    }

    /// Whether `value` is in the set.
    #[must_use]
    pub fn contains(self, value: AddValue) -> bool {
        self.0 & Self::bit(value) != 0
    }

    /// The values, in the manual's order.
    pub fn iter(self) -> impl Iterator<Item = AddValue> {
        AddValue::ALL.into_iter().filter(move |&v| self.contains(v))
    }

    /// How many values.
    #[must_use]
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    fn bit(value: AddValue) -> u8 {
        1 << AddValue::ALL.iter().position(|&v| v == value).unwrap_or(0)
    }
}

impl std::fmt::Display for AddValueSet {
    /// `NONE` or the words separated by blanks (`TEMP COUNTER`), as `OUTADD_RS422` takes them.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_empty() {
            return f.write_str("NONE");
        }
        let words: Vec<&str> = self.iter().map(AddValue::word).collect();
        f.write_str(&words.join(" "))
    }
}

impl serde::Serialize for AddValueSet {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.iter().map(|v| v.word().to_ascii_lowercase()))
    }
}

impl<'de> serde::Deserialize<'de> for AddValueSet {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let words = Vec::<String>::deserialize(deserializer)?;
        let values = words
            .iter()
            .map(|word| {
                AddValue::from_word(word).ok_or_else(|| {
                    serde::de::Error::custom(format!(
                        "`{word}` is not an ILD 2300 extra value (OUTADD_RS422: {})",
                        AddValue::ALL
                            .map(|v| v.word().to_ascii_lowercase())
                            .join(", ")
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(AddValueSet::of(&values))
    }
}

/// One value of an RS422 output cycle, as `GETOUTINFO_RS422` names it (A 6.5.2): a
/// displacement, the thickness, a statistic, or an extra value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OutputValue {
    /// Displacement 1 (`DIST1`): the distance.
    Dist1,
    /// Displacement 2 (`DIST2`, thickness measurement only).
    Dist2,
    /// The thickness between displacements 1 and 2 (`THICK12`).
    Thick12,
    /// A statistic (`MIN`, `MAX`, `PEAK2PEAK`).
    Statistic(&'static str),
    /// An extra value (`OUTADD_RS422`).
    Add(AddValue),
}

impl OutputValue {
    const STATISTICS: [&'static str; 3] = ["MIN", "MAX", "PEAK2PEAK"];

    /// The word `GETOUTINFO_RS422` lists it by.
    #[must_use]
    pub fn word(self) -> &'static str {
        match self {
            OutputValue::Dist1 => "DIST1",
            OutputValue::Dist2 => "DIST2",
            OutputValue::Thick12 => "THICK12",
            OutputValue::Statistic(word) => word,
            OutputValue::Add(value) => value.word(),
        }
    }

    /// The value a word names, in any case.
    #[must_use]
    pub fn from_word(word: &str) -> Option<OutputValue> {
        let known = [OutputValue::Dist1, OutputValue::Dist2, OutputValue::Thick12]
            .into_iter()
            .chain(Self::STATISTICS.map(OutputValue::Statistic));
        known
            .into_iter()
            .find(|value| value.word().eq_ignore_ascii_case(word))
            .or_else(|| AddValue::from_word(word).map(OutputValue::Add))
    }
}

/// What `GETOUTINFO_RS422` reports: the values of each output cycle, in the order they go out
/// on the line (A 6.5.2.1: "the sequence shown corresponds to the output sequence").
///
/// The reply's layout is not given in the manual, so the host reads every word of its
/// information lines that names an output value, in order, and passes over the rest (labels,
/// punctuation). The emulated sensor answers one value per line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IldOutputInfo {
    /// The values of a cycle, first to last.
    pub values: Vec<OutputValue>,
}

/// Why a `GETOUTINFO_RS422` reply could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IldOutputInfoError {
    /// The device answered with an error.
    #[error("GETOUTINFO_RS422 refused: E{code:02} {text}")]
    Refused {
        /// The error number.
        code: u8,
        /// Its text.
        text: String,
    },
    /// No word of the reply names an output value.
    #[error("GETOUTINFO_RS422 names no output value (reply lines {0:?})")]
    NoValues(Vec<String>),
}

impl IldOutputInfo {
    /// A cycle of the distance and then the extra values `extras`, in the manual's order (how
    /// the emulated sensor sends them).
    #[must_use]
    pub fn distance_then(extras: AddValueSet) -> IldOutputInfo {
        IldOutputInfo {
            values: std::iter::once(OutputValue::Dist1)
                .chain(extras.iter().map(OutputValue::Add))
                .collect(),
        }
    }

    /// The reply lines a device sends: one value per line.
    #[must_use]
    pub fn reply_lines(&self) -> Vec<String> {
        self.values.iter().map(|v| v.word().to_owned()).collect()
    }

    /// Reads a `GETOUTINFO_RS422` reply (host side).
    ///
    /// # Errors
    /// [`IldOutputInfoError`]: the device refused, or named no value.
    pub fn from_reply(reply: &IldReply) -> Result<IldOutputInfo, IldOutputInfoError> {
        if let Some(error) = &reply.error {
            return Err(IldOutputInfoError::Refused {
                code: error.code,
                text: error.text.clone(),
            });
        }
        let values: Vec<OutputValue> = reply
            .lines
            .iter()
            .flat_map(|line| line.split(|c: char| c.is_ascii_whitespace() || ",;:".contains(c)))
            .filter_map(OutputValue::from_word)
            .collect();
        if values.is_empty() {
            return Err(IldOutputInfoError::NoValues(reply.lines.clone()));
        }
        Ok(IldOutputInfo { values })
    }

    /// Where `value` is in the cycle (0: the first value).
    #[must_use]
    pub fn position(&self, value: OutputValue) -> Option<usize> {
        self.values.iter().position(|&v| v == value)
    }

    /// The extra values the cycle carries.
    #[must_use]
    pub fn extras(&self) -> AddValueSet {
        let adds: Vec<AddValue> = self
            .values
            .iter()
            .filter_map(|v| match v {
                OutputValue::Add(value) => Some(*value),
                _ => None,
            })
            .collect();
        AddValueSet::of(&adds)
    }

    /// The words, blank-separated, for messages (`DIST1 COUNTER`).
    #[must_use]
    pub fn words(&self) -> String {
        self.reply_lines().join(" ")
    }
}

/// A command of the subset. `None` parameters are queries.
#[derive(Debug, Clone, PartialEq)]
pub enum IldCommand {
    /// `GETINFO`: name, serial, measuring range, version.
    GetInfo,
    /// `GETOUTINFO_RS422`: the values of an RS422 output cycle, in their order.
    GetOutInfoRs422,
    /// `MEASRATE [1.5|2.5|5|10|20|30|49]`.
    MeasRate(Option<MeasuringRate>),
    /// `ECHO [ON|OFF]`.
    Echo(Option<bool>),
    /// `OUTDIST_RS422 [NONE|DIST1]`: the distance on RS422 off / on.
    OutDistRs422(Option<bool>),
    /// `OUTADD_RS422 [NONE|<value> ...]`: the extra values per cycle.
    OutAddRs422(Option<AddValueSet>),
    /// `BAUDRATE [baud]`.
    Baudrate(Option<u32>),
    /// `OUTPUT [NONE|RS422|ETHERNET]`: which interface outputs measured values.
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
            IldCommand::GetOutInfoRs422 => "GETOUTINFO_RS422",
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
            IldCommand::GetInfo | IldCommand::GetOutInfoRs422 => String::new(),
            IldCommand::MeasRate(rate) => rate.map(|r| r.word().to_owned()).unwrap_or_default(),
            IldCommand::Echo(on) => on.map(|on| on_off(on, ["OFF", "ON"])).unwrap_or_default(),
            IldCommand::OutDistRs422(on) => {
                on.map(|on| on_off(on, OUTDIST_WORDS)).unwrap_or_default()
            }
            IldCommand::OutAddRs422(values) => values.map(|v| v.to_string()).unwrap_or_default(),
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
        self.parameters().is_empty()
            && !matches!(self, IldCommand::GetInfo | IldCommand::GetOutInfoRs422)
    }

    /// The command line without its line end, e.g. `MEASRATE 20`.
    #[must_use]
    pub fn line(&self) -> String {
        let mut line = self.name().to_owned();
        let parameters = self.parameters();
        if !parameters.is_empty() {
            line.push(' ');
            line.push_str(&parameters);
        }
        line
    }

    /// The command line with its [`COMMAND_EOL`], e.g. `MEASRATE 20\r\n`.
    #[must_use]
    pub fn encode(&self) -> String {
        self.line() + COMMAND_EOL
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
            "GETINFO" | "GETOUTINFO_RS422" if !params.is_empty() => {
                return Err(wrong(if name == "GETINFO" {
                    "GETINFO"
                } else {
                    "GETOUTINFO_RS422"
                }));
            }
            "GETINFO" => IldCommand::GetInfo,
            "GETOUTINFO_RS422" => IldCommand::GetOutInfoRs422,
            "MEASRATE" => IldCommand::MeasRate(
                single("MEASRATE")?
                    .map(|p| MeasuringRate::from_word(p).ok_or_else(|| wrong("MEASRATE")))
                    .transpose()?,
            ),
            "ECHO" => IldCommand::Echo(word_index("ECHO", &["OFF", "ON"])?.map(|i| i == 1)),
            "OUTDIST_RS422" => IldCommand::OutDistRs422(
                word_index("OUTDIST_RS422", &OUTDIST_WORDS)?.map(|i| i == 1),
            ),
            "OUTADD_RS422" => IldCommand::OutAddRs422(match params.as_slice() {
                [] => None,
                [none] if none.eq_ignore_ascii_case("NONE") => Some(AddValueSet::NONE),
                words => Some(AddValueSet::of(
                    &words
                        .iter()
                        .map(|w| AddValue::from_word(w).ok_or_else(|| wrong("OUTADD_RS422")))
                        .collect::<Result<Vec<_>, _>>()?,
                )),
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
                word_index("OUTPUT", &OUTPUT_WORDS)?.map(|i| OUTPUT_WORDS[i].to_owned()),
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
    /// The repeated command line, when echo is on: the command as received, with
    /// [`ECHO_DONE_SUFFIX`] after a setting done (`MEASRATE 20 ok`).
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
    /// back with [`IldReply::queried`] (A 6.1, p. 122: "the reply can be used again as command
    /// for the parameter setting").
    #[must_use]
    pub fn query_answer(echo: Option<String>, setting: &IldCommand) -> IldReply {
        IldReply {
            echo,
            lines: vec![setting.line()],
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

/// Host-side incremental reply parser: push bytes, get whole replies at each `->`. It knows
/// the command line it waits on, so it tells the device's echo of it apart (the line itself,
/// or the line and [`ECHO_DONE_SUFFIX`]) whatever the device's echo setting: the host never
/// has to know it.
#[derive(Debug, Clone)]
pub struct IldReplyParser {
    sent: String,
    text: Vec<u8>,
}

impl IldReplyParser {
    /// A parser of the replies to `sent` (the command line, its line end left out).
    #[must_use]
    pub fn new(sent: &str) -> IldReplyParser {
        IldReplyParser {
            sent: normalised(sent),
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
                replies.push(parse_reply(&body, &self.sent));
                self.text.clear();
            }
        }
        replies
    }
}

/// A line with its blanks collapsed and in upper case, for comparing echoes.
fn normalised(line: &str) -> String {
    line.split_ascii_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_ascii_uppercase()
}

/// Splits a reply body (text before the prompt) into its parts; a first line that repeats
/// `sent` (normalised) is the echo.
fn parse_reply(body: &str, sent: &str) -> IldReply {
    let mut reply = IldReply::default();
    let mut lines = body
        .split(['\r', '\n'])
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .peekable();
    let done = format!("{sent}{}", ECHO_DONE_SUFFIX.to_ascii_uppercase());
    if let Some(first) = lines.next_if(|line| {
        let line = normalised(line);
        !sent.is_empty() && (line == sent || line == done)
    }) {
        reply.echo = Some(first.to_owned());
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
    /// The reply lines a device sends for `GETINFO` (without echo and prompt), in the order of
    /// the manual's example (A 6.3.1.2, p. 127); the keys this type does not hold get the
    /// values an emulated sensor has (`Option: 000`, a zero MAC address, `Name CalTab:
    /// DIFFUSE`, `Imagetype: factory`).
    #[must_use]
    pub fn reply_lines(&self) -> Vec<String> {
        vec![
            format!("Name: {}", self.name),
            format!("Serial: {}", self.serial),
            "Option: 000".to_owned(),
            format!("Article: {}", self.article),
            "MAC-Address: 00-00-00-00-00-00".to_owned(),
            format!("Measuring range: {:.2}mm", self.measuring_range_mm),
            "Name CalTab: DIFFUSE".to_owned(),
            format!("Version: {}", self.version),
            "Imagetype: factory".to_owned(),
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
            IldCommand::GetOutInfoRs422,
            IldCommand::MeasRate(Some(MeasuringRate::Khz49)),
            IldCommand::MeasRate(None),
            IldCommand::Echo(Some(false)),
            IldCommand::OutDistRs422(Some(true)),
            IldCommand::OutAddRs422(Some(AddValueSet::of(&[
                AddValue::Timestamp,
                AddValue::Counter,
            ]))),
            IldCommand::OutAddRs422(Some(AddValueSet::NONE)),
            IldCommand::Baudrate(Some(691_200)),
            IldCommand::Output(Some("RS422".to_owned())),
            IldCommand::Output(Some("ETHERNET".to_owned())),
            IldCommand::LaserPower(Some(false)),
            IldCommand::LaserPower(Some(true)),
            IldCommand::LaserPower(None),
        ];
        for command in commands {
            let line = command.encode();
            assert!(line.ends_with("\r\n"), "{line:?}");
            assert_eq!(IldCommand::parse(&line), Ok(command), "{line:?}");
        }
        assert_eq!(
            IldCommand::MeasRate(Some(MeasuringRate::Khz20)).encode(),
            "MEASRATE 20\r\n"
        );
        assert_eq!(
            IldCommand::OutAddRs422(Some(AddValueSet::of(&[
                AddValue::Counter,
                AddValue::Temperature
            ])))
            .encode(),
            "OUTADD_RS422 TEMP COUNTER\r\n",
            "the manual's order, whatever the order given"
        );
        assert_eq!(
            IldCommand::LaserPower(Some(true)).encode(),
            "LASERPOW FULL\r\n"
        );
    }

    #[test]
    fn the_top_rate_is_written_49_and_measures_at_49_14_khz() {
        assert_eq!(MeasuringRate::words(), "1.5|2.5|5|10|20|30|49");
        let top = MeasuringRate::from_hz(49_140.0).unwrap();
        assert_eq!(IldCommand::MeasRate(Some(top)).encode(), "MEASRATE 49\r\n");
        assert_eq!(top.hz(), 49_140.0);
        assert_eq!(MeasuringRate::from_word("49"), Some(top));
        assert_eq!(MeasuringRate::from_word("20.0"), Some(MeasuringRate::Khz20));
        assert_eq!(MeasuringRate::from_word("49.14"), None);
        assert!(IldCommand::parse("MEASRATE 49.14").is_err());
        assert_eq!(MeasuringRate::from_hz(49_000.0), None);
        assert_eq!(MeasuringRate::from_hz(12_000.0), None);
        for rate in MeasuringRate::ALL {
            assert_eq!(MeasuringRate::from_hz(rate.hz()), Some(rate));
            assert_eq!(MeasuringRate::from_word(rate.word()), Some(rate));
        }
    }

    #[test]
    fn only_the_2300s_outputs_are_taken() {
        assert!(IldCommand::parse("OUTPUT ETHERNET").is_ok());
        assert_eq!(
            IldCommand::parse("OUTPUT ANALOG"),
            Err(IldCommandError::WrongParameter {
                command: "OUTPUT",
                parameter: "ANALOG".to_owned()
            })
        );
        assert!(IldCommand::parse("OUTDIST_RS422 DIST2").is_err());
    }

    #[test]
    fn add_value_sets_iterate_in_the_manuals_order_and_read_json_words() {
        let set = AddValueSet::of(&[AddValue::State, AddValue::Temperature, AddValue::Counter]);
        assert_eq!(
            set.iter().collect::<Vec<_>>(),
            [AddValue::Temperature, AddValue::Counter, AddValue::State]
        );
        assert_eq!(set.len(), 3);
        assert!(set.contains(AddValue::Counter) && !set.contains(AddValue::Shutter));
        assert_eq!(set.to_string(), "TEMP COUNTER STATE");
        assert_eq!(AddValueSet::NONE.to_string(), "NONE");
        assert_eq!(
            serde_json::to_string(&set).unwrap(),
            r#"["temp","counter","state"]"#
        );
        let read: AddValueSet = serde_json::from_str(r#"["COUNTER", "temp"]"#).unwrap();
        assert_eq!(
            read,
            AddValueSet::of(&[AddValue::Temperature, AddValue::Counter])
        );
        let error = serde_json::from_str::<AddValueSet>(r#"["speed"]"#).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("`speed` is not an ILD 2300 extra value"),
            "{error}"
        );
    }

    #[test]
    fn a_query_answer_carries_the_setting_back() {
        let answer =
            IldReply::query_answer(None, &IldCommand::MeasRate(Some(MeasuringRate::Khz2_5)));
        assert_eq!(answer.encode(), "MEASRATE 2.5\r\n->");
        let parsed = IldReplyParser::new("MEASRATE").push(answer.encode().as_bytes());
        assert_eq!(
            parsed[0].queried("MEASRATE"),
            Some(IldCommand::MeasRate(Some(MeasuringRate::Khz2_5)))
        );
        assert_eq!(parsed[0].queried("BAUDRATE"), None);
        assert!(IldCommand::MeasRate(None).is_query());
        assert!(!IldCommand::GetInfo.is_query());
        assert!(!IldCommand::GetOutInfoRs422.is_query());
    }

    #[test]
    fn the_echo_is_told_apart_whatever_the_devices_setting() {
        // Echo on: a setting done is repeated with `ok`; a query and a refusal repeat the
        // line as it was sent (in any case and spacing); echo off: no echo at all.
        let cases = [
            (
                "MEASRATE 20",
                "measrate  20 ok\r\n->",
                Some("measrate  20 ok"),
                vec![],
            ),
            (
                "MEASRATE",
                "MEASRATE\r\nMEASRATE 20\r\n->",
                Some("MEASRATE"),
                vec!["MEASRATE 20"],
            ),
            ("MEASRATE", "MEASRATE 20\r\n->", None, vec!["MEASRATE 20"]),
            ("OUTPUT NONE", "->", None, vec![]),
            (
                "GETINFO",
                "GETINFO\r\nName: ILD2300\r\n->",
                Some("GETINFO"),
                vec!["Name: ILD2300"],
            ),
        ];
        for (sent, text, echo, lines) in cases {
            let reply = &IldReplyParser::new(sent).push(text.as_bytes())[0];
            assert_eq!(reply.echo.as_deref(), echo, "{sent:?}: {text:?}");
            assert_eq!(reply.lines, lines, "{sent:?}: {text:?}");
        }
        let refused =
            &IldReplyParser::new("MEASRATE 7").push(b"MEASRATE 7\r\nE04 Wrong parameter\r\n->")[0];
        assert_eq!(refused.echo.as_deref(), Some("MEASRATE 7"));
        assert_eq!(refused.error.as_ref().map(|e| e.code), Some(4));
    }

    #[test]
    fn getoutinfo_gives_the_order_of_the_values_on_the_line() {
        let info = IldOutputInfo::distance_then(AddValueSet::of(&[
            AddValue::Counter,
            AddValue::Temperature,
        ]));
        assert_eq!(info.words(), "DIST1 TEMP COUNTER");
        let reply = IldReply {
            lines: info.reply_lines(),
            ..IldReply::default()
        };
        assert_eq!(IldOutputInfo::from_reply(&reply), Ok(info.clone()));
        assert_eq!(info.position(OutputValue::Add(AddValue::Counter)), Some(2));
        assert_eq!(info.position(OutputValue::Dist1), Some(0));
        assert_eq!(
            info.extras(),
            AddValueSet::of(&[AddValue::Counter, AddValue::Temperature])
        );
        // Another layout: the words in order, labels and punctuation passed over.
        let other = IldReply {
            lines: vec!["RS422: COUNTER, DIST1".to_owned(), "speed".to_owned()],
            ..IldReply::default()
        };
        let read = IldOutputInfo::from_reply(&other).unwrap();
        assert_eq!(
            read.values,
            [OutputValue::Add(AddValue::Counter), OutputValue::Dist1]
        );
        assert_eq!(
            IldOutputInfo::from_reply(&IldReply::default()),
            Err(IldOutputInfoError::NoValues(vec![]))
        );
        let refused = IldReply::refusal(None, &IldCommandError::UnknownCommand("x".into()));
        assert!(matches!(
            IldOutputInfo::from_reply(&refused),
            Err(IldOutputInfoError::Refused { code: 1, .. })
        ));
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
        let reply = IldReply {
            echo: Some("GETINFO".to_owned()),
            lines: info.reply_lines(),
            ..IldReply::default()
        };
        let parsed = IldReplyParser::new("GETINFO").push(reply.encode().as_bytes());
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
        assert!(IldCommand::parse("GETOUTINFO_RS422 X").is_err());
        assert!(IldCommand::parse("OUTADD_RS422 NONE COUNTER").is_err());
    }

    #[test]
    fn replies_round_trip_through_the_host_parser() {
        let info = IldReply {
            echo: Some("GETINFO".to_owned()),
            lines: vec!["Name: ILD2300".into(), "Measuring range: 100.00mm".into()],
            ..IldReply::default()
        };
        let refusal = IldReply::refusal(
            Some("GETINFO".to_owned()),
            &IldCommand::parse("MEASRATE 7").unwrap_err(),
        );
        let text = info.encode() + &refusal.encode();
        let mut parser = IldReplyParser::new("GETINFO");
        // Byte by byte, as a serial line delivers it.
        let replies: Vec<_> = text.bytes().flat_map(|b| parser.push(&[b])).collect();
        assert_eq!(replies, vec![info, refusal.clone()]);
        assert_eq!(refusal.encode(), "GETINFO\r\nE04 Wrong parameter\r\n->");
    }
}
