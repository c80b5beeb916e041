//! Serial or parallel, by measuring: for passes that give the same bits either way (the
//! tensor-mass kernel's runs, the tree-split triangular solves), so the choice changes only
//! the time.
//!
//! Waking rayon's workers costs tens of microseconds per pass, and a loaded machine may have
//! no free core: a fixed size threshold made the tensor-mass kernel slower on two threads
//! than on one on both counts (54 passes per millisecond on the issue-24 beam at 20k), and
//! the 20k beam's triangular solve took 1.4 times longer on two threads than on one while
//! other builds held both cores.
//!
//! A calibration compares the median pass of each way, not their sums: one pass that meets
//! the host running something else on the other core takes several times its usual time,
//! and a sum carried it into the choice. The first calibration, right after the model is
//! built (cold caches, workers asleep), chose serial for the 20k beam's solve in 2 of 5
//! runs, and kept it for the next 2,048 solves, half of a one-second run. So the
//! interval between calibrations starts short and doubles while they agree, and falls back
//! to the shortest when one changes its mind: a wrong choice costs a few dozen passes.

use std::time::Duration;

/// Alternates a calibration's passes between the calling thread and rayon's (the first
/// `COLD` of the first calibration not counted) and keeps the way whose median pass is
/// faster by 10% until the next calibration.
#[derive(Clone, Debug, Default)]
pub struct Chooser {
    /// Passes since the last calibration ended (or since the start).
    pass: u32,
    /// Passes between calibrations now: `FIRST_INTERVAL` doubled for each calibration that
    /// agreed with the one before, up to `LAST_INTERVAL`; 0 before the first.
    interval: u32,
    /// The calibration's serial [0] and parallel [1] pass times.
    spent: [Vec<Duration>; 2],
    parallel: bool,
    /// Calibrations run (tests).
    calibrations: u32,
    /// Tests: always (`Some(true)`) or never in parallel.
    forced: Option<bool>,
}

impl Chooser {
    /// Passes of one calibration (half each way).
    const CALIBRATION: u32 = 16;
    /// Passes not counted at the very start.
    const COLD: u32 = 2;
    const FIRST_INTERVAL: u32 = 64;
    const LAST_INTERVAL: u32 = 2048;

    /// Whether the next pass runs on rayon's threads.
    pub fn pick(&self) -> bool {
        match self.forced {
            Some(on) => on,
            None if self.calibrating() => self.pass % 2 == 1,
            None => self.parallel,
        }
    }

    fn calibrating(&self) -> bool {
        self.pass < Self::CALIBRATION + self.cold()
    }

    fn cold(&self) -> u32 {
        if self.calibrations == 0 {
            Self::COLD
        } else {
            0
        }
    }

    /// The wall time of a pass run as `pick` said.
    pub fn record(&mut self, parallel: bool, took: Duration) {
        if self.forced.is_some() {
            return;
        }
        let calibrating = self.calibrating();
        if calibrating && self.pass >= self.cold() {
            self.spent[usize::from(parallel)].push(took);
        }
        self.pass += 1;
        if calibrating && !self.calibrating() {
            let [serial, par] = self.spent.each_mut().map(|s| median(s));
            let parallel = par < serial.mul_f64(0.9);
            self.interval = if self.calibrations > 0 && parallel == self.parallel {
                (2 * self.interval).min(Self::LAST_INTERVAL)
            } else {
                Self::FIRST_INTERVAL
            };
            self.parallel = parallel;
            self.calibrations += 1;
            self.spent.iter_mut().for_each(Vec::clear);
        } else if !calibrating && self.pass >= Self::CALIBRATION + self.interval {
            self.pass = 0;
        }
    }

    /// Tests: always in parallel (`Some(true)`), never, or as measured (`None`).
    #[cfg(test)]
    pub fn force(&mut self, on: Option<bool>) {
        self.forced = on;
    }
}

/// The median of `times` (the upper one of an even count); zero for none.
fn median(times: &mut [Duration]) -> Duration {
    times.sort_unstable();
    times.get(times.len() / 2).copied().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `passes` passes whose time is `cost(parallel, pass)`; returns the parallel ones.
    fn run(c: &mut Chooser, passes: u32, cost: impl Fn(bool, u32) -> u64) -> u32 {
        let mut parallel = 0;
        for i in 0..passes {
            let p = c.pick();
            parallel += u32::from(p);
            c.record(p, Duration::from_micros(cost(p, i)));
        }
        parallel
    }

    #[test]
    fn the_faster_way_is_kept_after_calibration() {
        for parallel_faster in [false, true] {
            let mut c = Chooser::default();
            let cost = |p: bool, _| if p == parallel_faster { 1000 } else { 3000 };
            run(&mut c, Chooser::COLD + Chooser::CALIBRATION, cost);
            assert_eq!(c.pick(), parallel_faster);
        }
        let mut c = Chooser::default();
        c.force(Some(true));
        assert!(c.pick());
    }

    /// One slow pass (the host took the core away for 20 ms) does not decide a calibration.
    #[test]
    fn one_stalled_pass_does_not_decide() {
        let mut c = Chooser::default();
        let cost = |p: bool, i: u32| match (p, i) {
            (true, 5) => 20_000,
            (true, _) => 1000,
            (false, _) => 1600,
        };
        run(&mut c, Chooser::COLD + Chooser::CALIBRATION, cost);
        assert!(c.pick());
    }

    /// A wrong first choice is revisited within a hundred passes, and agreeing calibrations
    /// space out to the longest interval, so calibrating costs a few percent at most.
    #[test]
    fn a_wrong_first_choice_is_short_lived_and_calibrations_space_out() {
        let mut c = Chooser::default();
        // Cold start: parallel looks slower for the first calibration only.
        let first = Chooser::COLD + Chooser::CALIBRATION;
        let cost = |p: bool, i: u32| match (p, i < first) {
            (true, true) => 3000,
            (true, false) => 1000,
            (false, _) => 1600,
        };
        run(&mut c, first, cost);
        assert!(!c.pick());
        let mut done = first;
        run(&mut c, 100, |p, i| cost(p, i + done));
        done += 100;
        assert_eq!(c.calibrations, 2);
        assert!(c.pick(), "the second calibration chose parallel");
        // From there on, serial passes are only the calibrations' halves.
        let passes = 40_000;
        let parallel = run(&mut c, passes, |p, i| cost(p, i + done));
        let serial_share = 1.0 - f64::from(parallel) / f64::from(passes);
        assert!(serial_share < 0.02, "{serial_share}");
        assert_eq!(c.interval, Chooser::LAST_INTERVAL);
    }
}
