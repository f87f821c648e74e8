//! Waiting for a controller outside the process (an isolated plugin's child, a HIL peer)
//! without mistaking a pause for the peer's silence.
//!
//! A process that is stopped and continued (Ctrl-Z then `fg`, a debugger, a cluster
//! scheduler's suspend) sees its timed waits fail with `EINTR` (a socket's receive timeout is
//! not restarted, signal(7)), or, restarted by the kernel, come back long after they were due.
//! Either way the time it spent stopped is nobody's answer being late: every wait here retries
//! an interrupted call, and a wait that came back [`PAUSE_GAP`] later than it asked (or was
//! interrupted) is a pause, after which the deadline it serves starts again.

use std::time::{Duration, Instant};

/// How much later than asked a wait may come back before it counts as a pause (s): far above
/// a busy machine's scheduling delay (milliseconds), far below a human's Ctrl-Z.
pub const PAUSE_GAP: Duration = Duration::from_millis(250);

/// A deadline `limit` after its start, restarted by a pause.
#[derive(Debug, Clone, Copy)]
pub struct Deadline {
    limit: Duration,
    at: Instant,
}

impl Deadline {
    /// `limit` from now.
    pub fn new(limit: Duration) -> Self {
        Self { limit, at: Instant::now() + limit }
    }

    /// The time left (zero when past).
    pub fn left(&self) -> Duration {
        self.at.saturating_duration_since(Instant::now())
    }

    /// Whether it is past.
    pub fn passed(&self) -> bool {
        Instant::now() >= self.at
    }

    /// The limit it was set to.
    pub fn limit(&self) -> Duration {
        self.limit
    }

    /// A pause ended now: the whole limit again from now.
    pub fn restart(&mut self) {
        self.at = Instant::now() + self.limit;
    }
}

/// Whether a wait that started at `started`, asked for `asked`, and came back now (or was
/// `interrupted`) spanned a pause of the process.
pub fn was_paused(started: Instant, asked: Duration, interrupted: bool) -> bool {
    interrupted || started.elapsed() > asked + PAUSE_GAP
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_late_or_interrupted_wait_is_a_pause_and_restarts_the_deadline() {
        let t0 = Instant::now() - Duration::from_secs(2);
        assert!(was_paused(t0, Duration::from_millis(10), false));
        assert!(!was_paused(Instant::now(), Duration::from_millis(10), false));
        assert!(was_paused(Instant::now(), Duration::from_millis(10), true));
        let mut d = Deadline::new(Duration::from_millis(1));
        std::thread::sleep(Duration::from_millis(3));
        assert!(d.passed() && d.left().is_zero());
        d.restart();
        assert!(!d.passed());
    }
}
