//! The onboard time base: `CLOCK_MONOTONIC`, shared by every process on the machine, in ns.

use iceoryx2_bb_posix::clock::{ClockType, Time};

/// Now on the monotonic clock, ns (0 if the clock cannot be read, which POSIX rules out for
/// `CLOCK_MONOTONIC`; a zero stamp reads as infinitely old everywhere, so it fails safe).
pub fn now_ns() -> u64 {
    Time::now_with_clock(ClockType::Monotonic)
        .map(|t| u64::try_from(t.as_duration().as_nanos()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Seconds between two stamps (`later − earlier`, negative if reversed).
pub fn secs_between(earlier_ns: u64, later_ns: u64) -> f64 {
    if later_ns >= earlier_ns {
        (later_ns - earlier_ns) as f64 * 1e-9
    } else {
        -((earlier_ns - later_ns) as f64 * 1e-9)
    }
}

/// At most one log line per period for a recurring problem (a babbling node on the CAN bus must
/// not flood the log or stall the loop that writes it); the counters keep the totals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Throttle {
    period_ns: u64,
    last_ns: Option<u64>,
    skipped: u64,
}

impl Throttle {
    /// One line per `period_ns` at most.
    pub const fn new(period_ns: u64) -> Self {
        Self { period_ns, last_ns: None, skipped: 0 }
    }

    /// Whether an occurrence at `now_ns` is logged: `Some(n)` with the number left out since the
    /// last line, or `None` (counted as left out).
    pub fn admit(&mut self, now_ns: u64) -> Option<u64> {
        if self.last_ns.is_some_and(|last| now_ns.saturating_sub(last) < self.period_ns) {
            self.skipped += 1;
            return None;
        }
        self.last_ns = Some(now_ns);
        Some(std::mem::take(&mut self.skipped))
    }
}

/// `" (N more since the last line)"` for `N > 0`, else nothing.
pub fn skipped_note(skipped: u64) -> String {
    if skipped > 0 { format!(" ({skipped} more since the last line)") } else { String::new() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_moves_forward() {
        let a = now_ns();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = now_ns();
        assert!(a > 0 && b > a);
        assert!(secs_between(a, b) >= 0.002);
        assert!(secs_between(b, a) < 0.0);
    }

    #[test]
    fn a_throttle_admits_one_line_per_period_and_counts_the_rest() {
        let mut t = Throttle::new(1_000);
        assert_eq!(t.admit(10), Some(0));
        assert_eq!(t.admit(500), None);
        assert_eq!(t.admit(1_009), None);
        assert_eq!(t.admit(1_010), Some(2));
        assert_eq!(t.admit(5_000), Some(0));
        // A clock that steps back does not silence it for long.
        assert_eq!(t.admit(100), None);
        assert_eq!(t.admit(6_000), Some(1));
        assert_eq!(skipped_note(0), "");
        assert_eq!(skipped_note(3), " (3 more since the last line)");
    }
}
