//! The line visibility estimator (section 4.2, eq. 3, Code 2).
//!
//! For the samples of the line being grown, `V_min` and `V_max` are the extreme lines that
//! cross every sample's uncertainty range `[near, far]`. Where they cross the next beam gives
//! the visibility `[d_min, d_max]`; a sample belongs to the line iff its own range overlaps it
//! (eq. 3).
//!
//! `V_max` always passes through the far bound of the sample that last forced an update (the
//! pivot) and the near bound of the most restrictive earlier sample; `V_min` the other way
//! round. When a new sample forces an update, the new most restrictive sample is searched only
//! from the previous one onwards (Code 2's `pos_min`): samples before it can never become more
//! restrictive, so there are no rescans.
//!
//! The search also skips samples that can never be restrictive: a near bound lying on the
//! sensor's side of the chord between its neighbours can never hold `V_max` back (any line
//! beyond both neighbours passes beyond it), and symmetrically for far bounds and `V_min`. The
//! candidates therefore form a convex chain, kept like a monotone-chain hull as samples arrive;
//! along it the angle seen from the pivot rises then falls, so the search stops at the first
//! fall. On a long straight wall this turns Code 2's worst case (every sample forcing a scan
//! back to the line's first) from quadratic into linear time; the result is the same.
//!
//! Most bounds never even join a chain: a near bound that lies short of `d_min` at its own
//! beam (a far bound beyond `d_max`) is passed beyond (short of) by every later bound line, so
//! it can never hold one back. Only the bounds of samples that moved `V_min` or `V_max` are
//! kept, a small fraction on a long wall. That took line inference on the bundled office from
//! 27 to 16 us a scan (`gema2 bench`), with the same lines.

use crate::sample::Sample;
use nalgebra::{Point2, Vector2};

/// A bound line `V_min` or `V_max`, through one sample's bound point `a` and an earlier one's
/// opposite bound point `b`, with what [`hit`] needs of it computed once: most samples cross a
/// bound line without moving it.
///
/// The direction is oriented so that `numerator` is positive: a beam `dir` then crosses the
/// line ahead of the sensor exactly where `cross(dir, e)` is positive, and one comparison with
/// `min_den` tells both that and whether the beam is too close to parallel.
#[derive(Clone, Copy, Debug, PartialEq)]
struct BoundLine {
    /// The line's direction, ±(b - a).
    e: Vector2<f64>,
    /// |cross(a, e)|: the distance along a beam is `numerator / cross(dir, e)`.
    numerator: f64,
    /// The smallest `cross(dir, e)` of a beam that crosses the line ahead of the sensor and
    /// not (nearly) parallel to it: 1e-12 |e|, or +inf for a line through the sensor.
    min_den: f64,
}

impl BoundLine {
    /// No bound yet (a line of one sample): crosses no beam.
    const NONE: BoundLine = BoundLine { e: Vector2::new(0.0, 0.0), numerator: 0.0, min_den: f64::INFINITY };

    fn through(a: Point2<f64>, b: Point2<f64>) -> Self {
        let e = b - a;
        let numerator = cross(&a.coords, &e);
        if numerator == 0.0 || numerator.is_nan() {
            return BoundLine::NONE;
        }
        let e = if numerator < 0.0 { -e } else { e };
        BoundLine { e, numerator: numerator.abs(), min_den: 1e-12 * e.norm().max(1e-12) }
    }

    /// Distance along the unit beam `dir` at which the line crosses it; `None` when it is
    /// parallel (|cross(dir, e)| < 1e-12 |e|) or crosses behind the sensor.
    #[inline]
    fn hit(&self, dir: Vector2<f64>) -> Option<f64> {
        let c = self.crossing(dir, Crossing::NONE);
        (c.den > 0.0).then(|| c.num / c.den)
    }

    /// [`hit`](Self::hit) as a fraction, `unbounded` where `hit` is `None`: no division.
    #[inline]
    fn crossing(&self, dir: Vector2<f64>, unbounded: Crossing) -> Crossing {
        let den = cross(&dir, &self.e);
        if den >= self.min_den {
            Crossing { num: self.numerator, den }
        } else {
            unbounded
        }
    }
}

/// A distance along a beam as the fraction `num / den` (both non-negative), so that comparing a
/// range with it takes a multiplication instead of a division: most samples are compared with
/// both bounds and move neither.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Crossing {
    num: f64,
    den: f64,
}

impl Crossing {
    /// No crossing, as [`BoundLine::hit`]'s `None`: 0 as a lower bound...
    const NONE: Crossing = Crossing { num: 0.0, den: 0.0 };
    const ZERO: Crossing = Crossing { num: 0.0, den: 1.0 };
    /// ...and +inf as an upper bound.
    const INFINITY: Crossing = Crossing { num: 1.0, den: 0.0 };

    /// Whether `d` lies below the crossing (`d < num / den`).
    #[inline]
    fn above(self, d: f64) -> bool {
        d * self.den < self.num
    }

    /// Whether `d` lies above the crossing (`d > num / den`).
    #[inline]
    fn below(self, d: f64) -> bool {
        d * self.den > self.num
    }

    fn distance(self) -> f64 {
        self.num / self.den
    }
}

/// Where `V_min` and `V_max` cross one sample's beam: the visibility `[d_min, d_max]` of eq. 3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    d_min: Crossing,
    d_max: Crossing,
}

impl Bounds {
    /// `d_min` and `d_max` in metres (0 and +inf where unbounded).
    pub fn distances(&self) -> (f64, f64) {
        (self.d_min.distance(), self.d_max.distance())
    }
}

/// The line visibility `V_l = (d_min, d_max)` of the line being inferred.
#[derive(Clone, Debug)]
pub struct LineVisibility {
    len: usize,
    /// [`BoundLine::NONE`] until the line has two samples.
    v_max: BoundLine,
    v_min: BoundLine,
    /// Position in `chain_near` of the most restrictive sample for `V_max` (Code 2's
    /// `pos_min`, kept across calls).
    restrictive_max: usize,
    /// Position in `chain_far` of the most restrictive sample for `V_min`.
    restrictive_min: usize,
    /// +1 when beams turn counter-clockwise, -1 otherwise: which side earlier samples lie on.
    turn: f64,
    /// Near bound points that can still constrain `V_max`, in sample order (a convex chain).
    chain_near: Vec<Point2<f64>>,
    /// Far bound points that can still constrain `V_min`.
    chain_far: Vec<Point2<f64>>,
}

impl LineVisibility {
    /// A visibility for an empty line; `angle_increment` gives the beams' turning direction.
    pub fn new(angle_increment: f64) -> Self {
        LineVisibility {
            len: 0,
            v_max: BoundLine::NONE,
            v_min: BoundLine::NONE,
            restrictive_max: 0,
            restrictive_min: 0,
            turn: if angle_increment < 0.0 { -1.0 } else { 1.0 },
            chain_near: Vec::new(),
            chain_far: Vec::new(),
        }
    }

    /// Starts a new line whose first sample is `samples[j]`.
    pub fn restart(&mut self, samples: &[Sample], j: usize) {
        self.len = 1;
        self.v_max = BoundLine::NONE;
        self.v_min = BoundLine::NONE;
        self.restrictive_max = 0;
        self.restrictive_min = 0;
        self.chain_near.clear();
        self.chain_far.clear();
        self.chain_near.push(samples[j].near_point());
        self.chain_far.push(samples[j].far_point());
    }

    /// Number of samples in the line.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// `[d_min, d_max]` along the beam of `s`: where `V_min` and `V_max` cross it. Unbounded
    /// sides (a line of one sample, or a bound line that never reaches the beam) are 0 / +inf.
    pub fn bounds(&self, s: &Sample) -> (f64, f64) {
        self.crossings(s).distances()
    }

    /// [`bounds`](Self::bounds) without divisions, for [`admits_within`](Self::admits_within)
    /// and [`include_within`](Self::include_within).
    #[inline]
    pub fn crossings(&self, s: &Sample) -> Bounds {
        Bounds {
            d_min: self.v_min.crossing(s.dir, Crossing::ZERO),
            d_max: self.v_max.crossing(s.dir, Crossing::INFINITY),
        }
    }

    /// Eq. 3: whether `s` can join the line, `[near, far]` overlapping `[d_min, d_max]`.
    pub fn admits(&self, s: &Sample) -> bool {
        self.admits_within(s, self.crossings(s))
    }

    /// Eq. 3 against bounds already computed with [`crossings`](Self::crossings).
    #[inline]
    pub fn admits_within(&self, s: &Sample, b: Bounds) -> bool {
        self.len == 0 || (!b.d_max.below(s.near) && !b.d_min.above(s.far))
    }

    /// Adds `samples[j]` (which must follow the line's last sample) and updates `V_min` and
    /// `V_max` as in Code 2.
    pub fn include(&mut self, samples: &[Sample], j: usize) {
        let b = self.crossings(&samples[j]);
        self.include_within(samples, j, b);
    }

    /// [`include`](Self::include) with the bounds on `samples[j]`'s beam already computed.
    #[inline]
    pub fn include_within(&mut self, samples: &[Sample], j: usize, b: Bounds) {
        if self.len == 0 {
            self.restart(samples, j);
            return;
        }
        let s = &samples[j];
        if b.d_max.above(s.far) {
            // Case B for V_max: pivot on s's far bound, constrained by an earlier near bound.
            let (at, q) = self.most_restrictive(s.far_point(), self.restrictive_max, true);
            self.v_max = BoundLine::through(s.far_point(), q);
            self.restrictive_max = at;
        }
        if b.d_min.below(s.near) {
            // The symmetric update of V_min: pivot on s's near bound, constrained by an
            // earlier far bound.
            let (at, q) = self.most_restrictive(s.near_point(), self.restrictive_min, false);
            self.v_min = BoundLine::through(s.near_point(), q);
            self.restrictive_min = at;
        }
        // A bound strictly inside the visibility at its own beam never becomes restrictive:
        // every later bound line crosses all the samples so far, so it passes beyond d_min
        // there (short of d_max), away from the bound. Only a sample that moved V_min (V_max)
        // can hold a later V_max (V_min) back, so only its near (far) bound joins a chain.
        // On a long wall that is a small fraction of the samples.
        // A most restrictive candidate dropped from its chain was followed only by dropped
        // ones, so the search resumes at the new sample, the first candidate after it.
        if !b.d_min.above(s.near) {
            let kept = push_chain(&mut self.chain_near, s.near_point(), true, self.turn);
            self.restrictive_max = self.restrictive_max.min(kept);
        }
        if !b.d_max.below(s.far) {
            let kept = push_chain(&mut self.chain_far, s.far_point(), false, self.turn);
            self.restrictive_min = self.restrictive_min.min(kept);
        }
        self.len += 1;
    }

    /// Code 2's loop: among the candidates from chain position `from` on, the one whose bound
    /// (near for `V_max`, far for `V_min`) makes the line through `pivot` most restrictive,
    /// as its chain position and point. Measured as the angle between the line and the
    /// direction from `pivot` back to the sensor: `V_max` takes the largest, `V_min` the
    /// smallest. Compared with cross products, no trigonometry.
    fn most_restrictive(&self, pivot: Point2<f64>, from: usize, for_max: bool) -> (usize, Point2<f64>) {
        let chain = if for_max { &self.chain_near } else { &self.chain_far };
        // the stored most restrictive candidate, or the first after it
        let mut pos = from.min(chain.len() - 1);
        let mut best_point = chain[pos];
        let mut best_dir = best_point - pivot;
        while pos + 1 < chain.len() {
            let q = chain[pos + 1];
            let dir = q - pivot;
            // Earlier samples lie on one side of the beam; on that side, `dir` makes a larger
            // angle with the direction to the sensor than `best_dir` iff it is turned further
            // against the beams' turning direction.
            let turned = self.turn * cross(&best_dir, &dir);
            if turned == 0.0 || (turned > 0.0) != for_max {
                break; // past the tangent: the angle only falls from here
            }
            (best_point, best_dir) = (q, dir);
            pos += 1;
        }
        (pos, best_point)
    }
}

/// Appends the newest sample's bound point `c` (its near bound when `near`) to a candidate
/// chain, first dropping the candidates that can no longer constrain: a near bound on the
/// sensor's side of the chord from its predecessor to the new one (a far bound on the far
/// side). `turn` is the beams' turning direction. Returns the position of the new candidate
/// (the number of candidates kept before it).
///
/// The sensor lies on the side of the chord from `a` to `c` that `turn` gives (cross(a, c) has
/// its sign): the samples of one line span less than half a turn, since a straight line seen
/// from a point does, and bound points lie ahead of the sensor.
#[inline]
fn push_chain(chain: &mut Vec<Point2<f64>>, c: Point2<f64>, near: bool, turn: f64) -> usize {
    // b with the sensor (near) or against it (far), or on the chord: never restrictive
    let sensor_side = if near { turn } else { -turn };
    // (a, b) = the last two kept candidates: each dropped b makes its predecessor the next b
    while let [.., a, b] = chain[..] {
        if cross(&(c - a), &(b - a)) * sensor_side < 0.0 {
            break;
        }
        chain.pop();
    }
    let kept = chain.len();
    chain.push(c);
    kept
}

#[inline]
fn cross(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Distance along the unit beam `dir` (from the sensor) at which the line through `a` and `b`
/// crosses it; `None` when it is parallel or crosses behind the sensor.
#[inline]
pub(crate) fn hit(a: Point2<f64>, b: Point2<f64>, dir: Vector2<f64>) -> Option<f64> {
    BoundLine::through(a, b).hit(dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::{build_samples, ErrorModel};
    use laser::{ScanGeometry, ScanView};
    use proptest::prelude::*;

    /// Samples of a straight wall `n . p = c`, given as `(angle of n, c)`, seen by beams
    /// `first..first + n` of `g`, plus deterministic noise (`noise[k]` in metres, or in error
    /// bands when `in_bands`).
    fn wall_samples(
        g: &ScanGeometry,
        first: usize,
        n: usize,
        (normal_angle, c): (f64, f64),
        e: &ErrorModel,
        noise: &[f64],
        in_bands: bool,
    ) -> Vec<Sample> {
        let nv = Vector2::new(normal_angle.cos(), normal_angle.sin());
        let ranges: Vec<f32> = (first..first + n)
            .map(|i| {
                let a = g.angle(i);
                let t = c / nv.dot(&Vector2::new(a.cos(), a.sin()));
                let k = noise[i % noise.len()];
                (t + if in_bands { k * e.at(t) } else { k }) as f32
            })
            .collect();
        let geometry = ScanGeometry { angle_min: g.angle(first), range_max: 100.0, ..*g };
        let mut samples = Vec::new();
        build_samples(&ScanView { geometry, ranges: &ranges }, e, 1, &mut samples);
        assert_eq!(samples.len(), n);
        samples
    }

    /// Brute force: every line through two bounds that crosses every sample's range; the
    /// smallest and largest distance at which they cross the next beam.
    fn brute_bounds(samples: &[Sample], next: &Sample) -> Option<(f64, f64)> {
        let mut pts = Vec::new();
        for s in samples {
            pts.push(s.near_point());
            pts.push(s.far_point());
        }
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for a in 0..pts.len() {
            for b in a + 1..pts.len() {
                if (pts[a] - pts[b]).norm() < 1e-9 {
                    continue;
                }
                let stabs = samples.iter().all(|s| match hit(pts[a], pts[b], s.dir) {
                    Some(t) => t >= s.near - 1e-9 && t <= s.far + 1e-9,
                    None => false,
                });
                if stabs {
                    if let Some(t) = hit(pts[a], pts[b], next.dir) {
                        lo = lo.min(t);
                        hi = hi.max(t);
                    }
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    #[test]
    fn accepts_every_sample_of_a_noisy_straight_wall() {
        let g = ScanGeometry::urg04lx();
        // noise of 80 % of e(d) at every reading, alternating sign: the worst zig-zag
        let e = ErrorModel::default();
        let seen = wall_samples(&g, 200, 300, (0.3, 2.0), &e, &[0.8, -0.8], true);
        let mut v = LineVisibility::new(g.angle_increment);
        for (j, s) in seen.iter().enumerate() {
            assert!(v.admits(s), "sample {j} of a straight wall rejected");
            v.include(&seen, j);
        }
        assert_eq!(v.len(), 300);
    }

    #[test]
    fn rejects_a_sample_whose_band_misses_every_line_through_the_wall() {
        let g = ScanGeometry::urg04lx();
        let e = ErrorModel::PAPER;
        let seen = wall_samples(&g, 300, 30, (0.0, 1.5), &e, &[0.0], false);
        let mut v = LineVisibility::new(g.angle_increment);
        for j in 0..20 {
            v.include(&seen, j);
        }
        let on = seen[20];
        assert!(v.admits(&on));
        // every line through the previous bands lies within about one band of the wall, so a
        // sample whose own band starts more than a band away (and a little wedge) is rejected
        for off in [-2.2, 2.2] {
            let d = on.d + off * e.at(on.d);
            let moved = Sample { d, near: d - e.at(d), far: d + e.at(d), ..on };
            assert!(!v.admits(&moved), "a sample {off} error bands off was admitted");
            let (lo, hi) = brute_bounds(&seen[..20], &moved).unwrap();
            assert!(moved.far < lo || moved.near > hi, "brute force disagrees");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The incremental bounds of Code 2 (with the stored most-restrictive index) equal the
        /// brute-force extremes of all lines through the samples' ranges.
        #[test]
        fn incremental_bounds_equal_brute_force(
            normal_angle in -0.6f64..0.6,
            c in 0.5f64..4.0,
            first in 250usize..400,
            n in 3usize..40,
            noise in proptest::collection::vec(-0.012f64..0.012, 16),
        ) {
            let g = ScanGeometry::urg04lx();
            let e = ErrorModel::PAPER;
            let seen = wall_samples(&g, first, n + 1, (normal_angle, c), &e, &noise, false);
            let mut v = LineVisibility::new(g.angle_increment);
            for j in 0..n {
                prop_assert!(v.admits(&seen[j]));
                v.include(&seen, j);
                if j >= 1 {
                    let next = &seen[j + 1];
                    let (lo, hi) = v.bounds(next);
                    let (blo, bhi) = brute_bounds(&seen[..=j], next).expect("a wall has stabbing lines");
                    prop_assert!((lo - blo).abs() < 1e-6, "d_min {} vs brute {}", lo, blo);
                    prop_assert!((hi - bhi).abs() < 1e-6, "d_max {} vs brute {}", hi, bhi);
                }
            }
        }
    }
}
