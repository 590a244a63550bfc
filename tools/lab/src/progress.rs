//! Progress that follows terminal conventions: on a terminal one line redrawn in place (`\r`), as
//! often as it changes; anywhere else (a log, CI, a pipe) a plain line at every tenth of the way
//! and at the end, never a carriage return.

use std::io::{IsTerminal as _, Write};

/// A progress line on a writer.
#[derive(Debug)]
pub struct Progress<W: Write> {
    out: W,
    tty: bool,
    /// The last tenth written as a plain line.
    last_tenth: Option<u32>,
}

impl Progress<std::io::Stderr> {
    /// On stderr (redrawn when stderr is a terminal).
    pub fn stderr() -> Self {
        let tty = std::io::stderr().is_terminal();
        Self::new(std::io::stderr(), tty)
    }
}

impl Progress<std::io::Stdout> {
    /// On stdout (redrawn when stdout is a terminal).
    pub fn stdout() -> Self {
        let tty = std::io::stdout().is_terminal();
        Self::new(std::io::stdout(), tty)
    }
}

impl<W: Write> Progress<W> {
    /// On `out`, redrawn in place when `tty`.
    pub fn new(out: W, tty: bool) -> Self {
        Self { out, tty, last_tenth: None }
    }

    /// `text` at `frac` (0–1) of the way.
    pub fn update(&mut self, frac: f64, text: &str) {
        if self.tty {
            let _ = write!(self.out, "\r{text}");
        } else {
            let tenth = (frac.clamp(0.0, 1.0) * 10.0).floor() as u32;
            if self.last_tenth.is_some_and(|t| t >= tenth) {
                return;
            }
            self.last_tenth = Some(tenth);
            let _ = writeln!(self.out, "{text}");
        }
        let _ = self.out.flush();
    }

    /// The last line: `text`, ending the redrawn one on a terminal.
    pub fn finish(&mut self, text: &str) {
        let _ = if self.tty { writeln!(self.out, "\r{text}") } else { writeln!(self.out, "{text}") };
        let _ = self.out.flush();
    }

    /// The writer (for tests).
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// A bar of `width` characters, `frac` (0–1) of it filled: `[#####.....]`.
pub fn bar(frac: f64, width: usize) -> String {
    let done = ((frac.clamp(0.0, 1.0) * width as f64) as usize).min(width);
    format!("[{}{}]", "#".repeat(done), ".".repeat(width - done))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn written(tty: bool) -> String {
        let mut p = Progress::new(Vec::new(), tty);
        for k in 0..=100 {
            p.update(f64::from(k) / 100.0, &format!("{} {k}/100", bar(f64::from(k) / 100.0, 10)));
        }
        p.finish("done");
        String::from_utf8(p.into_inner()).unwrap()
    }

    #[test]
    fn a_log_gets_a_line_per_tenth_and_no_carriage_return() {
        let log = written(false);
        assert!(!log.contains('\r'), "{log}");
        assert_eq!(log.lines().count(), 12, "0 %, each tenth to 100 %, and the end: {log}");
        assert!(log.starts_with("[..........] 0/100\n[#.........] 10/100\n"), "{log}");
        assert!(log.ends_with("[##########] 100/100\ndone\n"), "{log}");
    }

    #[test]
    fn a_terminal_gets_one_line_redrawn() {
        let term = written(true);
        assert_eq!(term.matches('\r').count(), 102);
        assert_eq!(term.matches('\n').count(), 1, "one line in all");
    }
}
