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
}
