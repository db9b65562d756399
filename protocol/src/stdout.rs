//! Printing to stdout whose failure is an error, never a panic: `println!` panics when stdout
//! cannot be written (`scanhil scan > /dev/full` once ended so, exit 101, after writing
//! everything). [`outln!`](crate::outln) is `println!` returning the error, naming stdout.

use std::io::{self, Write};

/// Writes `args` and a newline to stdout.
///
/// # Errors
/// The OS error, said to be stdout's (`writing to stdout: No space left on device ...`).
pub fn write_line(args: std::fmt::Arguments<'_>) -> io::Result<()> {
    let mut out = io::stdout().lock();
    out.write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(|error| io::Error::new(error.kind(), format!("writing to stdout: {error}")))
}

/// `println!` that returns an [`std::io::Result`] instead of panicking.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::stdout::write_line(format_args!($($arg)*))
    };
}
