//! A binary's output on stdout without `println!`'s panic when the reader went away.
//!
//! `println!` panics when stdout is a pipe whose reader closed it (`video2track sim card | head
//! -1`): Rust ignores SIGPIPE, so the write fails with `BrokenPipe`, and the workspace allows no
//! `unsafe` to restore the signal's default. [`out!`](crate::out) and [`outln!`](crate::outln)
//! write like `print!` and `println!` but return the failure as a [`StdoutError`]; a binary passes
//! it up with `?`, and its `main` ends quietly with exit 0 when [`closed`] finds
//! [`StdoutError::Closed`] among the error's causes: a reader that stopped reading is neither a
//! failure of the work nor bad input.
//!
//! ```
//! fn report() -> Result<(), v2t_files::stdout::StdoutError> {
//!     v2t_files::outln!("PET_min {:.2} s", 2.5)?;
//!     v2t_files::out!("{}", "no newline")
//! }
//! # report().unwrap();
//! ```

use std::io::Write as _;

/// Writing to stdout failed.
#[derive(Debug, thiserror::Error)]
pub enum StdoutError {
    /// The reader closed its end of the pipe (`| head`): the binary should end quietly, exit 0.
    #[error("stdout closed by its reader")]
    Closed,
    /// Any other failure (a full disk under a redirect).
    #[error("writing to stdout: {0}")]
    Write(std::io::Error),
}

impl From<std::io::Error> for StdoutError {
    fn from(e: std::io::Error) -> Self {
        if e.kind() == std::io::ErrorKind::BrokenPipe { Self::Closed } else { Self::Write(e) }
    }
}

/// Writes `args` to stdout, and a newline after them when `newline` (what [`out!`](crate::out)
/// and [`outln!`](crate::outln) call).
pub fn write(args: std::fmt::Arguments<'_>, newline: bool) -> Result<(), StdoutError> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)?;
    if newline {
        out.write_all(b"\n")?;
    }
    Ok(())
}

/// Whether `err` or one of its causes is [`StdoutError::Closed`]: the binary should end quietly
/// with exit 0, printing nothing.
pub fn closed(err: &(dyn std::error::Error + 'static)) -> bool {
    std::iter::successors(Some(err), |e| e.source())
        .any(|e| matches!(e.downcast_ref::<StdoutError>(), Some(StdoutError::Closed)))
}

/// Like `print!`, but returns `Result<(), StdoutError>` instead of panicking.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::stdout::write(::std::format_args!($($arg)*), false)
    };
}

/// Like `println!`, but returns `Result<(), StdoutError>` instead of panicking.
#[macro_export]
macro_rules! outln {
    () => {
        $crate::stdout::write(::std::format_args!(""), true)
    };
    ($($arg:tt)*) => {
        $crate::stdout::write(::std::format_args!($($arg)*), true)
    };
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("printing the report")]
    struct Outer(#[source] StdoutError);

    #[test]
    fn a_broken_pipe_is_closed_anywhere_in_the_chain_and_nothing_else_is() {
        let broken = StdoutError::from(std::io::Error::from(std::io::ErrorKind::BrokenPipe));
        assert!(matches!(broken, StdoutError::Closed));
        assert!(closed(&broken));
        assert!(closed(&Outer(broken)));
        let full = StdoutError::from(std::io::Error::from(std::io::ErrorKind::StorageFull));
        assert!(!closed(&full) && !closed(&Outer(full)));
        // A broken pipe to a child (ffmpeg's stdin) is a failure of the work, not a closed stdout.
        assert!(!closed(&std::io::Error::from(std::io::ErrorKind::BrokenPipe)));
    }
}
