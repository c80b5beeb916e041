//! What the simulation thread publishes for the page connections: the latest `init` message
//! (mesh, kinds, settings), the latest frame, and a short log of notices. Connections poll
//! it; nothing here waits on a page, so a slow or closed page never slows the simulation.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

/// Notices kept for connections that have not read them yet.
const NOTICES_KEPT: usize = 64;

/// A message and a counter that grows each time it is replaced.
#[derive(Clone, Debug, Default)]
pub struct Versioned {
    pub version: u64,
    pub text: Arc<String>,
}

/// The newest notice id, and the notices kept with their ids.
type NoticeLog = (u64, VecDeque<(u64, Arc<String>)>);

#[derive(Default)]
pub struct Hub {
    init: Mutex<Versioned>,
    frame: Mutex<Versioned>,
    notices: Mutex<NoticeLog>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A notice as the page receives it.
pub fn notice_json(level: &str, message: &str) -> String {
    serde_json::json!({ "type": "notice", "level": level, "message": message }).to_string()
}

impl Hub {
    pub fn set_init(&self, text: String) {
        let mut g = lock(&self.init);
        g.version += 1;
        g.text = Arc::new(text);
    }

    pub fn set_frame(&self, text: String) {
        let mut g = lock(&self.frame);
        g.version += 1;
        g.text = Arc::new(text);
    }

    pub fn init(&self) -> Versioned {
        lock(&self.init).clone()
    }

    pub fn frame(&self) -> Versioned {
        lock(&self.frame).clone()
    }

    /// Logs a notice to stderr and queues it for every page.
    pub fn notify(&self, level: &str, message: &str) {
        eprintln!("tissue view: {level}: {message}");
        let mut g = lock(&self.notices);
        g.0 += 1;
        let id = g.0;
        g.1.push_back((id, Arc::new(notice_json(level, message))));
        while g.1.len() > NOTICES_KEPT {
            g.1.pop_front();
        }
    }

    /// Notices after `seen`, and the id of the newest.
    pub fn notices_since(&self, seen: u64) -> (Vec<Arc<String>>, u64) {
        let g = lock(&self.notices);
        let new =
            g.1.iter()
                .filter(|(id, _)| *id > seen)
                .map(|(_, t)| Arc::clone(t))
                .collect();
        (new, g.0)
    }

    /// The id of the newest notice (a new page starts after it).
    pub fn last_notice(&self) -> u64 {
        lock(&self.notices).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notices_are_delivered_once_and_capped() {
        let h = Hub::default();
        h.notify("info", "a");
        let (n, last) = h.notices_since(0);
        assert_eq!((n.len(), last), (1, 1));
        for k in 0..100 {
            h.notify("error", &format!("{k}"));
        }
        let (n, last) = h.notices_since(1);
        assert_eq!((n.len(), last), (NOTICES_KEPT, 101));
        assert!(n.last().is_some_and(|t| t.contains("\"99\"")));
        assert!(h.notices_since(101).0.is_empty());
        h.set_frame("x".into());
        h.set_frame("y".into());
        assert_eq!(h.frame().version, 2);
        assert_eq!(h.frame().text.as_str(), "y");
    }
}
