//! What the tool says to people: results on stdout, progress and warnings on stderr.
//!
//! Writing to stdout returns an error instead of panicking (a closed pipe such as `| head`, or a
//! full disk behind `>`), so every command ends with a clean status after it has written its
//! files. Messages on stderr are best effort: when stderr itself is closed there is nobody to
//! tell, and a lost message must not cost a result.

use std::fmt;
use std::io::{self, Write};

/// Writes formatted text to stdout; an error (closed pipe, full disk) is returned.
pub fn out(arguments: fmt::Arguments<'_>) -> io::Result<()> {
    let mut stdout = io::stdout().lock();
    stdout.write_fmt(arguments)?;
    stdout.flush()
}

/// Writes formatted text to stderr, ignoring failures.
pub fn note(arguments: fmt::Arguments<'_>) {
    let mut stderr = io::stderr().lock();
    let _ = stderr.write_fmt(arguments);
    let _ = stderr.flush();
}

/// `outln!(...)`: one line on stdout, `io::Result<()>`.
#[macro_export]
macro_rules! outln {
    ($($argument:tt)*) => {
        $crate::console::out(format_args!("{}\n", format_args!($($argument)*)))
    };
}

/// `noteln!(...)`: one line on stderr, best effort.
#[macro_export]
macro_rules! noteln {
    ($($argument:tt)*) => {
        $crate::console::note(format_args!("{}\n", format_args!($($argument)*)))
    };
}

/// The message for an error and its causes, each cause once: a cause whose text the message
/// already contains (an error that prints its source) is not repeated.
pub fn error_message(error: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if text.is_empty() || message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    message
}

/// Whether the error is stdout (or another pipe) closed by the reader: the user piped into
/// `head` or closed the viewer, which is not worth an error message.
pub fn is_broken_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        let io_error = cause.downcast_ref::<io::Error>().or_else(|| {
            match cause.downcast_ref::<csv::Error>().map(csv::Error::kind) {
                Some(csv::ErrorKind::Io(error)) => Some(error),
                _ => None,
            }
        });
        io_error.is_some_and(|error| error.kind() == io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_printed_by_its_error_is_not_repeated() {
        let cause = io::Error::other("Not a typewriter");
        let error = anyhow::Error::new(cause).context("opening /dev/null: Not a typewriter");
        assert_eq!(error_message(&error), "opening /dev/null: Not a typewriter");
        let error = anyhow::anyhow!("EOF while parsing").context("reading c.json");
        assert_eq!(error_message(&error), "reading c.json: EOF while parsing");
    }

    #[test]
    fn broken_pipe_is_recognised_through_context() {
        let error = anyhow::Error::new(io::Error::from(io::ErrorKind::BrokenPipe))
            .context("writing the table");
        assert!(is_broken_pipe(&error));
        assert!(!is_broken_pipe(&anyhow::anyhow!("other")));
    }
}
