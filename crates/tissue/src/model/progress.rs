//! A handle through which long pre-computations (condensation, tensor pre-computation, BEM
//! assembly) report how far they have gone, so the CLI can draw a progress bar. Models that
//! pre-compute keep the handle they were given and report to it; silent by default.

use std::fmt;
use std::sync::Arc;

type Callback = dyn Fn(&str, f64) + Send + Sync;

/// Receives (stage, fraction done in 0..=1).
#[derive(Clone, Default)]
pub struct Progress(Option<Arc<Callback>>);

impl Progress {
    pub fn new(report: impl Fn(&str, f64) + Send + Sync + 'static) -> Self {
        Self(Some(Arc::new(report)))
    }

    /// A handle that reports nowhere.
    pub fn silent() -> Self {
        Self(None)
    }

    pub fn report(&self, stage: &str, fraction: f64) {
        if let Some(f) = &self.0 {
            f(stage, fraction.clamp(0.0, 1.0));
        }
    }
}

impl fmt::Debug for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(reporting)"
        } else {
            "Progress(silent)"
        })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    #[test]
    fn reports_reach_the_callback_clamped() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sink = seen.clone();
        let p = Progress::new(move |stage, f| sink.lock().unwrap().push((stage.to_string(), f)));
        p.report("condensing", 0.5);
        p.clone().report("condensing", 1.5);
        Progress::silent().report("nothing", 0.1);
        let seen = seen.lock().unwrap();
        assert_eq!(
            seen.as_slice(),
            &[
                ("condensing".to_string(), 0.5),
                ("condensing".to_string(), 1.0)
            ]
        );
    }
}
