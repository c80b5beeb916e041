//! Timing statistics of the haptic loop: a latency histogram with 1 µs bins, so that recording
//! a tick never allocates and percentiles are exact to the microsecond.

use std::time::Duration;

use serde::Serialize;

use crate::math::Real;

/// Latencies above this land in the last bin (they are deadline misses anyway).
const BINS: usize = 20_000;

/// Latency histogram and deadline accounting of a periodic loop.
#[derive(Clone, Debug)]
pub struct TimingStats {
    period: Duration,
    bins: Vec<u32>,
    ticks: u64,
    missed: u64,
    max_ns: u64,
    elapsed: Duration,
}

/// What the statistics say, in the units `tissue haptic-bench` prints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TimingSummary {
    /// Ticks run.
    pub ticks: u64,
    /// Ticks per second of wall time.
    pub rate_hz: Real,
    /// Median latency from the scheduled tick to the force being published, in µs.
    pub p50_us: Real,
    /// 99th percentile of the same, in µs.
    pub p99_us: Real,
    pub max_us: Real,
    /// Ticks whose force came later than one period after the scheduled time, plus ticks
    /// skipped because the loop had fallen behind.
    pub missed_deadlines: u64,
}

impl TimingStats {
    pub fn new(period: Duration) -> Self {
        Self {
            period,
            bins: vec![0; BINS],
            ticks: 0,
            missed: 0,
            max_ns: 0,
            elapsed: Duration::ZERO,
        }
    }

    pub fn period(&self) -> Duration {
        self.period
    }

    /// Records one tick that published its force `latency` after its scheduled time.
    pub fn record(&mut self, latency: Duration) {
        let us = usize::try_from(latency.as_micros()).unwrap_or(usize::MAX);
        if let Some(b) = self.bins.get_mut(us.min(BINS - 1)) {
            *b = b.saturating_add(1);
        }
        self.ticks += 1;
        self.max_ns = self
            .max_ns
            .max(u64::try_from(latency.as_nanos()).unwrap_or(u64::MAX));
        if latency > self.period {
            self.missed += 1;
        }
    }

    /// Counts ticks that were never run because the loop was late by whole periods.
    pub fn record_skipped(&mut self, count: u64) {
        self.missed += count;
    }

    /// Sets the wall time the ticks took, for the rate.
    pub fn set_elapsed(&mut self, elapsed: Duration) {
        self.elapsed = elapsed;
    }

    /// Latency below which a fraction `q` (0..=1) of the ticks fall, in µs (upper bin edge).
    pub fn quantile_us(&self, q: Real) -> Real {
        if self.ticks == 0 {
            return 0.0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.ticks as Real).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (us, &n) in self.bins.iter().enumerate() {
            seen += u64::from(n);
            if seen >= rank {
                return (us + 1) as Real;
            }
        }
        BINS as Real
    }

    pub fn summary(&self) -> TimingSummary {
        let secs = self.elapsed.as_secs_f64();
        TimingSummary {
            ticks: self.ticks,
            rate_hz: if secs > 0.0 {
                self.ticks as Real / secs
            } else {
                0.0
            },
            p50_us: self.quantile_us(0.5),
            p99_us: self.quantile_us(0.99),
            max_us: self.max_ns as Real / 1e3,
            missed_deadlines: self.missed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut s = TimingStats::new(us(1000));
        // 1..=1000 µs plus 0.5 µs: each bin [k, k+1) µs holds one sample.
        for k in 0..1000u64 {
            s.record(us(k) + Duration::from_nanos(500));
        }
        s.set_elapsed(Duration::from_secs(2));
        let m = s.summary();
        assert_eq!(m.ticks, 1000);
        assert_eq!(m.p50_us, 500.0); // rank 500 -> bin 499 -> upper edge 500 µs
        assert_eq!(m.p99_us, 990.0);
        assert_eq!(m.rate_hz, 500.0);
        assert_eq!(m.max_us, 999.5);
        // 999.5 µs is within the 1000 µs period: no miss.
        assert_eq!(m.missed_deadlines, 0);
    }

    #[test]
    fn late_and_skipped_ticks_are_misses() {
        let mut s = TimingStats::new(us(1000));
        s.record(us(999));
        s.record(us(1000)); // exactly on the deadline is in time
        s.record(us(1001));
        s.record(Duration::from_secs(3600)); // far beyond the histogram: clamped, counted
        s.record_skipped(5);
        let m = s.summary();
        assert_eq!(m.missed_deadlines, 2 + 5);
        assert_eq!(m.ticks, 4);
        assert_eq!(s.quantile_us(1.0), BINS as Real);
        assert_eq!(m.max_us, 3.6e9);
    }

    #[test]
    fn empty_stats_are_zero() {
        let m = TimingStats::new(us(1000)).summary();
        assert_eq!(m, TimingSummary::default());
    }
}
