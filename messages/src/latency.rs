//! What the stamps a pose carries measure, defined once for every reader: `gema2 run`'s
//! report, the recorder, and `gema2 inspect` of its recording print the same figures, from the
//! same stamps, with the same quantiles.
//!
//! Every figure comes from the pose message's header, which carries each stage's enter and
//! leave times as the scan passed it. (The recorder once took the segment stage's time from
//! the lines message, stamped before the corners were published, and ended "end to end" where
//! localize let the pose go while `gema2 run` ended it where the supervisor took it: one run
//! read 73.8 us p50 for segment in one and 55.4 in the other.)

use crate::{Header, Stage};
use std::collections::VecDeque;

/// One latency figure: the key the recorder logs it under (`latency/<key>`) and its label.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Figure {
    pub key: &'static str,
    pub label: &'static str,
}

/// The figures of a pose, in pipeline order.
pub const FIGURES: [Figure; 6] = [
    Figure { key: "acquire", label: "acquire stage" },
    Figure { key: "hop/scan", label: "hop acquire -> segment" },
    Figure { key: "segment", label: "segment stage" },
    Figure { key: "hop/corners", label: "hop segment -> localize" },
    Figure { key: "localize", label: "localize stage" },
    Figure { key: "end_to_end", label: "end to end (acquisition -> pose published)" },
];

/// Microseconds from `from_ns` to `to_ns`; NaN when either stamp is missing (0) or they run
/// backwards.
pub fn between_us(from_ns: u64, to_ns: u64) -> f64 {
    if from_ns == 0 || to_ns < from_ns {
        f64::NAN
    } else {
        (to_ns - from_ns) as f64 / 1e3
    }
}

/// The [`FIGURES`] of a pose's header, microseconds (NaN where a stamp is missing).
pub fn of_pose(h: &Header) -> [f64; 6] {
    let [a, s, l] = [Stage::Acquire, Stage::Segment, Stage::Localize].map(|k| h.stages[k as usize]);
    [
        between_us(a.enter_ns, a.leave_ns),
        between_us(a.leave_ns, s.enter_ns),
        between_us(s.enter_ns, s.leave_ns),
        between_us(s.leave_ns, l.enter_ns),
        between_us(l.enter_ns, l.leave_ns),
        between_us(h.stamp_ns, l.leave_ns),
    ]
}

/// The latest `kept` values of a figure: what a report of a run reads. A pipeline on a robot
/// runs for days; keeping every value would grow without end.
#[derive(Clone, Debug)]
pub struct Latest<T> {
    values: VecDeque<T>,
    kept: usize,
}

impl<T> Latest<T> {
    pub fn new(kept: usize) -> Self {
        Latest { values: VecDeque::new(), kept: kept.max(1) }
    }

    /// Keeps `value`, letting the oldest go when `kept` are held.
    pub fn push(&mut self, value: T) {
        if self.values.len() == self.kept {
            self.values.pop_front();
        }
        self.values.push_back(value);
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.values.iter()
    }
}

/// p50 and p99 of the finite `values` (nearest rank); NaN when there are none.
pub fn p50_p99(values: &[f64]) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    (at(0.5), at(0.99))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StageSpan;

    #[test]
    fn the_figures_of_a_pose_chain_its_stamps() {
        let mut h = Header::new(1, 1_000);
        h.stages = [
            StageSpan { enter_ns: 1_000, leave_ns: 3_000 },
            StageSpan { enter_ns: 4_000, leave_ns: 9_000 },
            StageSpan { enter_ns: 10_000, leave_ns: 20_000 },
        ];
        assert_eq!(of_pose(&h), [2.0, 1.0, 5.0, 1.0, 10.0, 19.0]);
        h.stages[1] = StageSpan::default();
        let f = of_pose(&h);
        assert!(f[1].is_nan() && f[2].is_nan() && f[3].is_nan() && f[5] == 19.0);
    }

    #[test]
    fn the_latest_values_are_kept_and_the_oldest_let_go() {
        let mut l = Latest::new(3);
        assert!(l.is_empty());
        for v in 1..=5 {
            l.push(v);
        }
        assert_eq!(l.iter().copied().collect::<Vec<_>>(), [3, 4, 5]);
        assert_eq!(l.len(), 3);
    }

    #[test]
    fn quantiles_are_nearest_rank_and_skip_missing_values() {
        let v: Vec<f64> = (1..=100).map(f64::from).chain([f64::NAN]).collect();
        assert_eq!(p50_p99(&v), (50.0, 99.0));
        assert_eq!(p50_p99(&[7.0]), (7.0, 7.0));
        assert!(p50_p99(&[f64::NAN]).0.is_nan());
    }
}
