//! One time type for the whole session, and an injectable clock.
//!
//! Every sample carries a [`TimeNs`]: nanoseconds on the *session clock*, a
//! monotonic clock that starts at 0 when the session's rig is created. On the
//! simulated rig the session clock is simulated time ([`SimClock`]); on the
//! real rig it is the host's monotonic clock ([`WallClock`]). Device clocks
//! (a camera driver's timestamps, a sensor's own counter) are a different
//! domain and are mapped onto the session clock by an offset captured at
//! start, in the backend that owns them.

use std::fmt;
use std::ops::{Add, Sub};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// A point on the session clock, in nanoseconds since the session started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct TimeNs(pub u64);

impl TimeNs {
    /// The start of the session.
    pub const ZERO: TimeNs = TimeNs(0);

    /// Time from seconds (rounded to the nearest nanosecond; negative values clamp to 0).
    pub fn from_secs_f64(t_s: f64) -> TimeNs {
        TimeNs((t_s.max(0.0) * 1e9).round() as u64)
    }

    /// Time in seconds.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }

    /// `self - earlier` in seconds, negative when `earlier` is later.
    pub fn secs_since(self, earlier: TimeNs) -> f64 {
        (self.0 as i128 - earlier.0 as i128) as f64 * 1e-9
    }

    /// `self - earlier`, or zero when `earlier` is later.
    pub fn saturating_since(self, earlier: TimeNs) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl Add<Duration> for TimeNs {
    type Output = TimeNs;
    fn add(self, d: Duration) -> TimeNs {
        TimeNs(self.0.saturating_add(d.as_nanos() as u64))
    }
}

impl Sub<TimeNs> for TimeNs {
    type Output = Duration;
    /// Saturating: a later `rhs` gives zero.
    fn sub(self, rhs: TimeNs) -> Duration {
        self.saturating_since(rhs)
    }
}

impl fmt::Display for TimeNs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6} s", self.as_secs_f64())
    }
}

/// The session clock.
///
/// # Contract
/// - `now` is monotonic and never blocks.
/// - `sleep_until` returns once `now() >= t`. A simulated clock jumps there at
///   once; a wall clock sleeps. It returns immediately when `t` is past.
/// - Clones share one time: advancing one clone advances all of them.
pub trait Clock: Send + Sync {
    /// Current session time.
    fn now(&self) -> TimeNs;
    /// Waits (or, on simulated time, jumps) until `now() >= t`.
    fn sleep_until(&self, t: TimeNs);
    /// True when time advances by itself (wall clock), false on simulated time.
    fn is_realtime(&self) -> bool;
}

/// Simulated time: advances only through [`Clock::sleep_until`], so a loop
/// runs as fast as the CPU allows. Clones share the same time.
#[derive(Clone, Debug, Default)]
pub struct SimClock {
    now_ns: Arc<AtomicU64>,
}

impl SimClock {
    /// A simulated clock at time 0.
    pub fn new() -> SimClock {
        SimClock::default()
    }
}

impl Clock for SimClock {
    fn now(&self) -> TimeNs {
        TimeNs(self.now_ns.load(Ordering::Acquire))
    }
    fn sleep_until(&self, t: TimeNs) {
        self.now_ns.fetch_max(t.0, Ordering::AcqRel);
    }
    fn is_realtime(&self) -> bool {
        false
    }
}

/// Wall time: the host's monotonic clock, 0 at creation (or at first use).
/// Clones share the origin.
#[derive(Clone, Debug)]
pub struct WallClock {
    /// The host instant of session time 0, set when the clock is first read
    /// if it was not at creation.
    origin: Arc<OnceLock<Instant>>,
}

impl WallClock {
    /// A wall clock whose time 0 is now.
    pub fn start() -> WallClock {
        WallClock { origin: Arc::new(OnceLock::from(Instant::now())) }
    }

    /// A wall clock whose time 0 is when it is first read (or slept on):
    /// for a simulated rig in real time, whose set-up (the camera's renderer,
    /// the session file) must not count as time the devices already ran.
    pub fn start_on_first_use() -> WallClock {
        WallClock { origin: Arc::new(OnceLock::new()) }
    }

    /// The host instant of session time 0 (for mapping device clocks).
    pub fn origin(&self) -> Instant {
        *self.origin.get_or_init(Instant::now)
    }
}

impl Clock for WallClock {
    fn now(&self) -> TimeNs {
        TimeNs(self.origin().elapsed().as_nanos() as u64)
    }
    fn sleep_until(&self, t: TimeNs) {
        let now = self.now();
        if t > now {
            std::thread::sleep(t - now);
        }
    }
    fn is_realtime(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clock_started_on_first_use_counts_from_then_and_clones_share_it() {
        let clock = WallClock::start_on_first_use();
        let copy = clock.clone();
        std::thread::sleep(Duration::from_millis(50));
        // Time 0 is now, not when the clock was made 50 ms ago.
        assert!(copy.now() < TimeNs(40_000_000), "{:?}", copy.now());
        std::thread::sleep(Duration::from_millis(20));
        let (a, b) = (clock.now(), copy.now());
        assert!(a >= TimeNs(20_000_000) && b >= a, "{a:?} {b:?}");
        assert_eq!(clock.origin(), copy.origin());
    }

    #[test]
    fn sim_clock_clones_share_time_and_never_go_back() {
        let a = SimClock::new();
        let b = a.clone();
        a.sleep_until(TimeNs(5_000));
        assert_eq!(b.now(), TimeNs(5_000));
        b.sleep_until(TimeNs(1_000));
        assert_eq!(a.now(), TimeNs(5_000), "a simulated clock is monotonic");
    }

    #[test]
    fn wall_clock_sleeps_until_the_deadline() {
        let c = WallClock::start();
        let t = c.now() + Duration::from_millis(3);
        c.sleep_until(t);
        assert!(c.now() >= t);
    }

    #[test]
    fn conversions_round_trip() {
        assert_eq!(TimeNs::from_secs_f64(1.5).0, 1_500_000_000);
        assert_eq!(TimeNs(2_500_000_000).as_secs_f64(), 2.5);
        assert_eq!(TimeNs(1).secs_since(TimeNs(3)), -2e-9);
        assert_eq!(TimeNs(1) - TimeNs(3), Duration::ZERO);
    }
}
