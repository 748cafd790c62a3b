//! When to seed Nav2's AMCL on `/initialpose`: with an `ok` pose, at most once per period. AMCL
//! restarts its particle filter on every initial pose, so it is seeded, not spammed.

use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub struct Seeding {
    every: Duration,
    last: Option<Instant>,
}

impl Seeding {
    /// At most one seed per `every`.
    pub fn new(every: Duration) -> Self {
        Seeding { every, last: None }
    }

    /// Whether an answer at `now`, `ok` or not, goes to `/initialpose` (and counts as sent).
    pub fn admit(&mut self, ok: bool, now: Instant) -> bool {
        let due = self.last.is_none_or(|t| now.duration_since(t) >= self.every);
        if ok && due {
            self.last = Some(now);
        }
        ok && due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_ok_answers_seed_and_no_more_often_than_asked() {
        let t0 = Instant::now();
        let mut s = Seeding::new(Duration::from_secs(5));
        assert!(!s.admit(false, t0), "an ambiguous answer never seeds");
        assert!(s.admit(true, t0));
        assert!(!s.admit(true, t0 + Duration::from_secs(4)));
        assert!(s.admit(true, t0 + Duration::from_secs(5)));
    }
}
