//! Unwrapping the adapter's timestamps, which count milliseconds modulo one
//! minute.

use super::wire::TIMESTAMP_PERIOD_MS;

/// Turns the adapter's frame timestamps (milliseconds modulo 60000) into a
/// monotonic count of milliseconds on the adapter's clock.
///
/// # Contract
/// - The first timestamp maps to itself (0 to 59999): results count
///   milliseconds from the start of the adapter's minute in which the first
///   timestamped frame arrived. They never decrease.
/// - [`unwrap`](Self::unwrap) takes each timestamp to follow the previous
///   one by less than a minute: a step backwards is one wrap. A silence of
///   a minute or more is invisible in the timestamps alone.
/// - [`unwrap_at`](Self::unwrap_at) also takes the host's reception time and
///   adds the whole minutes the host's clock says passed since the previous
///   frame (host latency of up to 30 s is absorbed).
/// - A value of 60000 or more (no adapter should send one) is rejected:
///   `None`, the state unchanged, counted in [`rejected`](Self::rejected).
#[derive(Clone, Debug, Default)]
pub struct SlcanClock {
    last: Option<Last>,
    rejected: u64,
}

#[derive(Clone, Copy, Debug)]
struct Last {
    raw: u16,
    ms: u64,
    host_ms: Option<u64>,
}

impl SlcanClock {
    /// A clock that has seen no timestamp yet.
    pub fn new() -> SlcanClock {
        SlcanClock::default()
    }

    /// The monotonic time (ms) of the next timestamp `raw_ms`.
    pub fn unwrap(&mut self, raw_ms: u16) -> Option<u64> {
        self.advance(raw_ms, None)
    }

    /// The monotonic time (ms) of the next timestamp `raw_ms`, received at
    /// `host_ms` on a monotonic host clock (milliseconds, any origin).
    pub fn unwrap_at(&mut self, raw_ms: u16, host_ms: u64) -> Option<u64> {
        self.advance(raw_ms, Some(host_ms))
    }

    /// Timestamps rejected as out of range.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    fn advance(&mut self, raw: u16, host_ms: Option<u64>) -> Option<u64> {
        if raw >= TIMESTAMP_PERIOD_MS {
            self.rejected += 1;
            return None;
        }
        let period = u64::from(TIMESTAMP_PERIOD_MS);
        let ms = match self.last {
            None => u64::from(raw),
            Some(last) => {
                let step = (u64::from(raw) + period - u64::from(last.raw)) % period;
                let minutes = match (host_ms, last.host_ms) {
                    // The whole periods that best explain the host's elapsed time.
                    (Some(now), Some(then)) => {
                        (now.saturating_sub(then).saturating_sub(step) + period / 2) / period
                    }
                    _ => 0,
                };
                last.ms + step + minutes * period
            }
        };
        self.last = Some(Last { raw, ms, host_ms });
        Some(ms)
    }
}
