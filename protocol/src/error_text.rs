//! An error and its causes on one line, as the programs print them.
//!
//! Many errors quote their cause in their own message (`cannot open slcan:/dev/x: No such
//! file or directory (os error 2)`) and also return it as [`std::error::Error::source`], so
//! printing the whole chain (`{:#}` of an `anyhow::Error`) said the OS error twice.
//! [`chain_text`] joins the chain with `: ` and leaves out a cause whose text is already in
//! the line.

use std::error::Error;

/// `error` and its causes joined with `: `, each cause said once: one already quoted in the
/// text so far is left out.
#[must_use]
pub fn chain_text(error: &(dyn Error + 'static)) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(next) = cause {
        let next_text = next.to_string();
        if !text.contains(&next_text) {
            text.push_str(": ");
            text.push_str(&next_text);
        }
        cause = next.source();
    }
    text
}

#[cfg(test)]
mod tests {
    use super::chain_text;

    /// An error that quotes its source in its message and also returns it.
    #[derive(Debug, thiserror::Error)]
    #[error("cannot open {what}: {source}")]
    struct Quoting {
        what: &'static str,
        source: std::io::Error,
    }

    /// An error that only returns its source.
    #[derive(Debug, thiserror::Error)]
    #[error("scan {0}")]
    struct Context(&'static str, #[source] Quoting);

    #[test]
    fn a_quoted_os_error_is_said_once_and_a_silent_context_keeps_its_cause() {
        let os = std::io::Error::from_raw_os_error(2);
        let os_text = os.to_string();
        let error = Context(
            "a.json",
            Quoting {
                what: "slcan:/dev/x",
                source: os,
            },
        );
        assert_eq!(
            chain_text(&error),
            format!("scan a.json: cannot open slcan:/dev/x: {os_text}")
        );
    }
}
