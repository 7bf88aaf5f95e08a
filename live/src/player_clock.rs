//! The playback clock: which log time is due now, at a speed, with pauses.

use std::time::{Duration, Instant};

/// Maps log time (ns) to wall time: `anchor_log` was due at `anchor_wall`,
/// and log time runs `speed` times as fast as the wall clock.
#[derive(Clone, Debug)]
pub(crate) struct PlayClock {
    anchor_wall: Instant,
    anchor_log_ns: u64,
    speed: f64,
    /// The log time the clock stopped at, while paused.
    paused_at_ns: Option<u64>,
}

impl PlayClock {
    /// A clock at which `log_ns` is due now.
    pub(crate) fn start(log_ns: u64, speed: f64) -> PlayClock {
        PlayClock { anchor_wall: Instant::now(), anchor_log_ns: log_ns, speed, paused_at_ns: None }
    }

    /// The log time due now (ns).
    pub(crate) fn now_ns(&self) -> u64 {
        match self.paused_at_ns {
            Some(t) => t,
            None => {
                let wall_ns = self.anchor_wall.elapsed().as_secs_f64() * 1e9;
                self.anchor_log_ns.saturating_add((wall_ns * self.speed) as u64)
            }
        }
    }

    /// How long until `log_ns` is due; `None` when it is due already.
    /// Paused, it is never due: the answer is a long wait.
    pub(crate) fn wait_for(&self, log_ns: u64) -> Option<Duration> {
        if self.paused_at_ns.is_some() {
            return Some(Duration::from_secs(1));
        }
        let due = self.anchor_wall
            + Duration::from_secs_f64(log_ns.saturating_sub(self.anchor_log_ns) as f64 / 1e9 / self.speed);
        due.checked_duration_since(Instant::now()).filter(|d| !d.is_zero())
    }

    /// Stops the clock where it is.
    pub(crate) fn pause(&mut self) {
        if self.paused_at_ns.is_none() {
            self.paused_at_ns = Some(self.now_ns());
        }
    }

    /// Runs the clock again from where it stopped.
    pub(crate) fn resume(&mut self) {
        if let Some(t) = self.paused_at_ns.take() {
            self.anchor_log_ns = t;
            self.anchor_wall = Instant::now();
        }
    }

    /// Changes the speed from now on.
    pub(crate) fn set_speed(&mut self, speed: f64) {
        if self.paused_at_ns.is_none() {
            self.anchor_log_ns = self.now_ns();
            self.anchor_wall = Instant::now();
        }
        self.speed = speed;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_runs_at_its_speed_and_stands_still_while_paused() {
        let mut clock = PlayClock::start(1_000, 2.0);
        let wait = clock.wait_for(1_000 + 200_000_000).expect("100 ms of wall time at 2x");
        assert!(wait <= Duration::from_millis(100) && wait > Duration::from_millis(90), "{wait:?}");
        assert_eq!(clock.wait_for(500), None, "the past is due");
        clock.pause();
        let t = clock.now_ns();
        std::thread::sleep(Duration::from_millis(5));
        assert_eq!(clock.now_ns(), t);
        clock.resume();
        assert!(clock.now_ns() >= t);
    }
}
