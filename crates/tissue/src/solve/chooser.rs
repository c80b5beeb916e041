//! Serial or parallel, by measuring: for passes that give the same bits either way (the
//! tensor-mass kernel's runs, the tree-split triangular solves), so the choice changes only
//! the time.
//!
//! Waking rayon's workers costs tens of microseconds per pass, and a loaded machine may have
//! no free core: a fixed size threshold made the tensor-mass kernel slower on two threads
//! than on one on both counts (54 passes per millisecond on the issue-24 beam at 20k), and
//! the 20k beam's triangular solve took 1.4 times longer on two threads than on one while
//! other builds held both cores.

use std::time::Duration;

/// Every `RECALIBRATE` passes the next `CALIBRATION` alternate between the calling thread
/// and rayon's (the first two, cold, not counted), and the faster by 10% in wall time is
/// kept until the next calibration.
#[derive(Clone, Debug, Default)]
pub struct Chooser {
    pass: u32,
    /// Wall time of the calibration's serial [0] and parallel [1] passes.
    spent: [Duration; 2],
    parallel: bool,
    /// Tests: always (`Some(true)`) or never in parallel.
    forced: Option<bool>,
}

impl Chooser {
    const CALIBRATION: u32 = 18;
    const RECALIBRATE: u32 = 2048;

    /// Whether the next pass runs on rayon's threads.
    pub fn pick(&self) -> bool {
        match self.forced {
            Some(on) => on,
            None if self.pass < Self::CALIBRATION => self.pass % 2 == 1,
            None => self.parallel,
        }
    }

    /// The wall time of a pass run as `pick` said.
    pub fn record(&mut self, parallel: bool, took: Duration) {
        if (2..Self::CALIBRATION).contains(&self.pass) {
            self.spent[usize::from(parallel)] += took;
        }
        self.pass += 1;
        if self.pass == Self::CALIBRATION {
            self.parallel = self.spent[1] < self.spent[0].mul_f64(0.9);
            self.spent = Default::default();
        } else if self.pass >= Self::RECALIBRATE {
            self.pass = 0;
        }
    }

    /// Tests: always in parallel (`Some(true)`), never, or as measured (`None`).
    #[cfg(test)]
    pub fn force(&mut self, on: Option<bool>) {
        self.forced = on;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_faster_way_is_kept_after_calibration() {
        for parallel_faster in [false, true] {
            let mut c = Chooser::default();
            for _ in 0..Chooser::CALIBRATION {
                let p = c.pick();
                let ms = if p == parallel_faster { 1 } else { 3 };
                c.record(p, Duration::from_millis(ms));
            }
            assert_eq!(c.pick(), parallel_faster);
        }
        let mut c = Chooser::default();
        c.force(Some(true));
        assert!(c.pick());
    }
}
