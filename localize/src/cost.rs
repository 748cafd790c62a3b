//! The cost function (section 5.2, eq. 7): how well the ranges an ideal sensor would read at a
//! pose, d'_i, explain the measured d_i.
//!
//! Eq. 7 sums (d_i - d'_i)^2. Unmapped objects (people, furniture) make it prefer wrong poses
//! (docs/how-it-works.md, "Where the paper falls short"), so the default [`CostKind::OneSided`] form normalises each residual by the
//! sensor's noise at that range and caps it differently on each side: a reading *shorter* than
//! the map predicts can be an object in front of the wall and costs at most `front_cap`; a
//! reading *longer* than the map predicts means seeing through a mapped wall and costs up to
//! `through_cap`. A beam with no return where the map predicts a wall in range costs
//! `through_cap` too; unknown readings (NaN, error codes) carry no information and are skipped.
//! So are missing returns in a scan that shows its sensor reporting lost returns as "no
//! return" ([`surface_dropouts`]).
//!
//! A short reading's cap also depends on how far short it falls ([`CostConfig::clutter_share`]):
//! furniture stands against walls, so a surface the map lacks a few tenths of a metre in front
//! of the wall the beam was going to meet is what a right pose sees, while a surface metres
//! short of it, out in open floor, is what a wrong pose makes of the scan (docs/how-it-works.md, "Where the paper falls short", item 2:
//! the true pose of a furnished scan often cost more than a wrong one, whose unexplained
//! readings float in the open).
//!
//! `through_cap` weighs a wrong pose's beams through walls against the right pose's beams
//! through walls the map has but the world no longer does (a door drawn closed, a wall built
//! from a parked trolley). At 25 (5 sigma squared) the simulated logs, whose maps have no such
//! walls, did best, but right poses against the maps built from the CARMEN logs lost to wrong
//! ones: 12 (about 3.5 sigma squared) took their success from 54.5 / 44.8 / 48.6 % to
//! 56.8 / 58.1 / 63.0 % with ok precision 85-94 % -> 89-100 %, and cost the simulated logs at
//! most 0.6 points (furnished radial), with the furnished warehouse's ok precision up from 86.4
//! to 89.1 %. 9 gained a few more points on the CARMEN logs and lost 1-1.4 on every furnished
//! simulated log.

use laser::Pose;
use laser::{Reading, ScanView};
use map::{RayCaster, RayScratch};
use segment::ErrorModel;

/// Which form of eq. 7.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CostKind {
    /// The paper's sum of squared residuals over valid readings (metres squared, per beam).
    Paper,
    /// Noise-normalised, one-sided capped residuals (see the module docs).
    OneSided,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostConfig {
    pub kind: CostKind,
    /// Cap of a residual in front of the map's wall, in squared standard deviations.
    pub front_cap: f64,
    /// Cap of a residual behind the map's wall (or a missing return).
    pub through_cap: f64,
    /// Skip missing returns, as unknown readings: set for a scan whose sensor loses returns
    /// on surfaces it sees ([`surface_dropouts`]), where "no return" does not say that nothing
    /// is there.
    pub skip_no_returns: bool,
    /// Every how many beams to evaluate (the paper's equispaced subset); 1 = all.
    pub stride: usize,
    /// Smallest residual standard deviation, metres: raised when costing poses that are not
    /// yet refined, so a few centimetres of misalignment do not read as a wrong pose, and to the
    /// map's stated accuracy.
    pub sigma_floor: f64,
    /// The floor is a distance across the wall (a wall drawn off its place, a pose a little
    /// off); along a beam that meets the wall at incidence alpha it is floor / cos(alpha), at
    /// most this many times the floor. The cost uses that; agreement and seeing through walls
    /// (`inliers`, `through`) are still judged across the wall. 1 turns it off. On the CARMEN
    /// maps (floor 0.1 m) beams grazing a wall drawn a few centimetres off its place read as
    /// seeing through it at the right pose: with 3, aces went from 56.8 to 61.4 % success (ok
    /// precision 88.5 -> 90.0 %), freiburg-101 from 76.7 to 77.4 %, csail from 62.6 to 61.6 %;
    /// judging agreement along the beam too gave 61.4 / 62.1 / 79.5 % but 8 more wrong `ok`
    /// answers. The simulated logs' maps state no error, so only their coarse cost (floor
    /// 0.08 m) changes: over 39 logs, 16 more successes and 1 fewer wrong `ok` (77).
    pub grazing_cap: f64,
    /// Cap of a reading short of the map by as much as furniture stands out from a wall, as a
    /// share of `front_cap`: between `clutter_min` and `clutter_reach` short of the wall the
    /// map puts along its beam. From there the cap rises linearly to `front_cap` at 1.5
    /// `clutter_reach`; beyond, and where the map puts no wall in range, a surface in open
    /// floor costs `front_cap`. 1 turns this off. Measured over the 48 simulated logs of `gema2
    /// evaluate` (see the README); maps built from scans have their own share
    /// ([`crate::LocalizerConfig::clutter_share_approximate`]).
    ///
    /// Judged along the beam, not by the reading's distance to whichever wall is nearest: a
    /// wrong pose in a dense map puts its short readings beside some wall or other almost
    /// anywhere, and so shared the discount. Against that form: clean 68-beam scans 89.3 ->
    /// 91.3 % on the office (92.3 % with no discount), `ok` over the 48 logs 11369 -> 11591,
    /// successes 13763 -> 13775, the furnished warehouse 81.7 -> 80.3 %.
    pub clutter_share: f64,
    /// Less than this short of the wall, a reading is the pose's misalignment, not an object in
    /// front of the wall (real furniture is deeper): it keeps `front_cap`. Without this floor,
    /// wrong poses a few centimetres to a decimetre off a wall got the discount on that wall's
    /// readings and came within the ambiguity margin of the truth (`ok` 2862 against 2915 over
    /// the bundled maps' 12 logs at 0.2 m, same successes).
    pub clutter_min: f64,
    /// How far from a wall furniture reaches, metres (a cabinet, a desk, a shelf: 0.3-0.9 m).
    pub clutter_reach: f64,
    /// Between cast beams at most this many radians apart (0: never), a beam reading beyond the
    /// wall the map puts along it is not counted as seeing through walls (`through`) when it
    /// reads no further than the wall a neighbouring beam meets and its other neighbour does
    /// not see through: it passes the end of a wall, and at the right pose refined to a few
    /// millimetres and a tenth of a degree, some beams always do. The cost is unchanged. Every
    /// wall end in view makes one such beam now and then, so a long-range sensor in a drawn map
    /// saw through 1-2 % of its beams at the right pose and escalated: a 30 m sensor in the
    /// bundled warehouse (`gema2 sim --range-max 30`) ran the grid search on 40 % of its clean
    /// scans. Off on a map built from scans (the localizer turns it off): its walls are broken
    /// into short pieces, and a wrong pose's beams pass their ends too; on, the CARMEN logs'
    /// wrong `ok` went from 7 to 23.
    pub edge_step: f64,
}

impl Default for CostConfig {
    fn default() -> Self {
        CostConfig {
            kind: CostKind::OneSided,
            front_cap: 4.0,
            through_cap: 12.0,
            skip_no_returns: false,
            stride: 1,
            sigma_floor: 0.0,
            grazing_cap: 3.0,
            clutter_share: 0.5,
            clutter_min: 0.2,
            clutter_reach: 0.8,
            edge_step: 1.2f64.to_radians(),
        }
    }
}

impl CostConfig {
    /// The cap of a reading `short_by` metres short of the wall the map puts along its beam
    /// (see [`clutter_share`](Self::clutter_share)).
    pub fn front_cap_at(&self, short_by: f64) -> f64 {
        if self.clutter_share >= 1.0 || short_by < self.clutter_min {
            return self.front_cap;
        }
        let least = self.clutter_share * self.front_cap;
        least + (self.front_cap - least) * self.openness(short_by)
    }

    /// How far into open floor a surface `from_wall` metres out from a wall stands: 0 up to
    /// `clutter_reach` (where furniture stands), rising linearly to 1 at 1.5 times it.
    pub fn openness(&self, from_wall: f64) -> f64 {
        let ramp = 0.5 * self.clutter_reach;
        if ramp <= 0.0 {
            return 1.0;
        }
        ((from_wall - self.clutter_reach) / ramp).clamp(0.0, 1.0)
    }
}

/// The cost of one pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cost {
    /// Mean cost per evaluated beam (lower is better).
    pub value: f64,
    /// Fraction of evaluated beams within three standard deviations of the map.
    pub inliers: f64,
    /// Fraction of evaluated beams that see through a mapped wall by more than three standard
    /// deviations (or miss a wall the map puts in range).
    pub through: f64,
    pub beams: u32,
}

/// Evaluates eq. 7 at `pose`. `expected` and `scratch` are reusable buffers.
pub fn cost(
    scan: &ScanView<'_>,
    pose: &Pose,
    caster: &RayCaster,
    error: &ErrorModel,
    cfg: &CostConfig,
    scratch: &mut RayScratch,
    expected: &mut Vec<f64>,
) -> Cost {
    cost_below(scan, pose, caster, error, cfg, f64::INFINITY, scratch, expected)
}

/// Beams cast at a time by [`cost_below`] when it can stop early.
const PART: usize = 8;

/// [`cost`], stopping as soon as the pose is known to cost more than `bound` (a mean per beam):
/// then `value` is +inf. Every beam's term is non-negative, and with the one-sided form the
/// beams counted do not depend on the pose, so the sum so far over the beams the pose will be
/// judged on bounds its cost from below. A pose that is not stopped gets exactly [`cost`]'s
/// value. Only casts that march their beams one by one can stop early (a long reach in a large
/// map); a sweep casts every beam at once. The paper's form counts only the beams the map
/// puts in range, so its poses are never stopped.
#[allow(clippy::too_many_arguments)]
pub fn cost_below(
    scan: &ScanView<'_>,
    pose: &Pose,
    caster: &RayCaster,
    error: &ErrorModel,
    cfg: &CostConfig,
    bound: f64,
    scratch: &mut RayScratch,
    expected: &mut Vec<f64>,
) -> Cost {
    let g = scan.geometry;
    let stride = cfg.stride.max(1);
    let step = g.angle_increment.abs() * stride as f64;
    let stoppable = cfg.kind == CostKind::OneSided && bound < f64::INFINITY;
    // the sum the pose may reach before it is stopped: bound times the beams the mean is taken
    // over, which the pose does not change; counted only for a cast in parts
    let mut limit = None;
    let (mut sum, mut inliers, mut through, mut beams) = (0.0, 0u32, 0u32, 0u32);
    let mut done = 0;
    let mut over = false;
    // no term above this can come down (with `clutter_share` at 1, none is above it)
    let least_front = cfg.clutter_share * cfg.front_cap;
    let part = if stoppable { PART } else { usize::MAX };
    caster.cast_while(pose, &g, scan.len(), stride, part, scratch, expected, |expected, cast| {
        // a beam's term reads its neighbours' expected ranges: the last one cast waits for the next
        let ready = if cast == expected.len() { cast } else { cast.saturating_sub(1) };
        for (k, &d_map) in expected.iter().enumerate().take(ready).skip(done) {
            let reading = scan.reading(k * stride);
            if let Some((mut c, verdict)) = beam_term(reading, d_map, expected, k, step, error, cfg, scan, stride) {
                if let (Reading::Valid(d), Verdict::Other) = (reading, &verdict) {
                    // only short of a wall the map puts in range
                    if d < d_map && d_map < g.range_max && c > least_front {
                        c = c.min(cfg.front_cap_at(d_map - d));
                    }
                }
                sum += c;
                beams += 1;
                match verdict {
                    Verdict::Inlier => inliers += 1,
                    Verdict::Through => through += 1,
                    Verdict::Other => {}
                }
            }
        }
        done = done.max(ready);
        if stoppable && cast < expected.len() {
            // a hair above, so that rounding never stops a pose whose mean would not pass `bound`
            let limit = *limit.get_or_insert_with(|| {
                let judged = (0..expected.len()).filter(|&k| !skipped(scan.reading(k * stride), cfg)).count();
                bound * judged as f64 * (1.0 + 1e-12)
            });
            over = sum > limit;
        }
        !over
    });
    if over || beams == 0 {
        return Cost { value: f64::INFINITY, inliers: 0.0, through: 0.0, beams };
    }
    let n = beams as f64;
    Cost { value: sum / n, inliers: inliers as f64 / n, through: through as f64 / n, beams }
}

/// Whether the cost leaves out a beam reading `reading`, whatever the map predicts: an
/// unknown reading always, a lost return when configured so.
#[inline]
fn skipped(reading: Reading, cfg: &CostConfig) -> bool {
    match reading {
        Reading::Unknown => true,
        Reading::NoReturn => cfg.skip_no_returns,
        Reading::Valid(_) => false,
    }
}

/// How one beam's reading stands against the map.
enum Verdict {
    /// Within three standard deviations of the map.
    Inlier,
    /// Seeing through a mapped wall, or missing a wall the map puts in range.
    Through,
    Other,
}

/// The term of eq. 7 for beam `k` (the `k`-th cast), reading `reading` where the map predicts
/// `d_map`; `None` for a beam the cost skips.
#[allow(clippy::too_many_arguments)]
#[inline]
fn beam_term(
    reading: Reading,
    d_map: f64,
    expected: &[f64],
    k: usize,
    step: f64,
    error: &ErrorModel,
    cfg: &CostConfig,
    scan: &ScanView<'_>,
    stride: usize,
) -> Option<(f64, Verdict)> {
    if skipped(reading, cfg) {
        return None;
    }
    let g = &scan.geometry;
    // the sensor's sigma at this range, and the floor across the wall: agreement and seeing
    // through are judged against it
    let sensor = error.at(d_map) / 3.0;
    let across = sensor.max(cfg.sigma_floor);
    let in_range = d_map < g.range_max;
    match (reading, cfg.kind) {
        (Reading::Unknown, _) => None, // skipped above
        (Reading::Valid(d), CostKind::Paper) => {
            if !in_range {
                return None;
            }
            let verdict = if ((d - d_map) / across).abs() <= 3.0 { Verdict::Inlier } else { Verdict::Other };
            Some(((d - d_map).powi(2), verdict))
        }
        (_, CostKind::Paper) => None,
        (Reading::Valid(d), CostKind::OneSided) => {
            if !in_range {
                return Some((cfg.front_cap, Verdict::Other));
            }
            let residual_sq = (d - d_map) * (d - d_map);
            let across_sq = across * across;
            let verdict = if residual_sq <= 9.0 * across_sq {
                Verdict::Inlier
            } else if d > d_map
                && !(step <= cfg.edge_step && at_edge(d, expected, k, 3.0 * across, |j| scan.reading(j * stride)))
            {
                Verdict::Through
            } else {
                Verdict::Other
            };
            // the floor along this beam, which the cost uses (squared: no root)
            let along_sq = if cfg.sigma_floor > sensor && cfg.grazing_cap > 1.0 {
                let secant_sq = incidence_secant_sq(expected, k, step).min(cfg.grazing_cap.powi(2));
                (sensor * sensor).max(cfg.sigma_floor * cfg.sigma_floor * secant_sq)
            } else {
                across_sq
            };
            let z_sq = residual_sq / along_sq;
            Some((z_sq.min(if d > d_map { cfg.through_cap } else { cfg.front_cap }), verdict))
        }
        (Reading::NoReturn, CostKind::OneSided) => {
            if in_range && d_map < g.range_max - 3.0 * across {
                Some((cfg.through_cap, Verdict::Through))
            } else {
                Some((0.0, Verdict::Inlier))
            }
        }
    }
}

/// Whether beam `k`, reading `d` beyond the wall the map puts along it, passes the end of
/// that wall ([`CostConfig::edge_step`]): a neighbouring beam's wall, beyond a jump of the
/// expected ranges, is no nearer than the reading (within `slack`), and the beam on the other
/// side does not see through its own wall. At the right pose, a pose a hair turned or moved
/// puts such a beam past the end; a wrong pose that misplaces a wall's end sees through a run
/// of beams, of which only the last reaches the wall beyond, and counts that run but its
/// last. `reading(j)` is the reading of the `j`-th cast beam.
fn at_edge(d: f64, expected: &[f64], k: usize, slack: f64, reading: impl Fn(usize) -> Reading) -> bool {
    let reaches = |j: usize| expected.get(j).is_some_and(|&e| d <= e + slack);
    // a neighbour past the last cast beam, or with no reading, sees through nothing
    let clear = |j: Option<usize>| {
        j.and_then(|j| expected.get(j).map(|&e| (j, e))).is_none_or(|(j, e)| match reading(j) {
            Reading::Valid(r) => r <= e + slack,
            // no return is seeing through a wall the map puts in range
            Reading::NoReturn => e.is_infinite(),
            Reading::Unknown => true,
        })
    };
    let before = k.checked_sub(1);
    (before.is_some_and(reaches) && clear(Some(k + 1))) || (reaches(k + 1) && clear(before))
}

/// 1 / cos^2 of the incidence of beam `k` on the wall it meets, from how fast the expected
/// range changes between neighbouring beams (`step` radians apart): dr / dphi = r tan(alpha).
/// The smaller change of either side is used, so a jump from one wall to another does not count.
fn incidence_secant_sq(expected: &[f64], k: usize, step: f64) -> f64 {
    let d = expected[k];
    let before = k.checked_sub(1).map_or(f64::INFINITY, |j| (d - expected[j]).abs());
    let after = expected.get(k + 1).map_or(f64::INFINITY, |&e| (e - d).abs());
    let change = before.min(after);
    1.0 + (change * change) / (step * step * d * d)
}

/// Runs of at most [`laser::MAX_LOST_RETURNS`] missing returns between two valid readings that
/// agree with each other within their errors, well inside the sensor's range (70 % of it):
/// returns lost on a surface seen on both sides. A sensor that reports "no return" only where nothing is in range never
/// gives one; a SICK LMS, which reads 81.91 m for a lost return, gives them on dark or distant
/// walls. Linear in the scan's length.
pub fn surface_dropouts(scan: &ScanView<'_>, error: &ErrorModel) -> usize {
    let inside = 0.7 * scan.geometry.range_max;
    let mut count = 0;
    // the valid reading right before the current position, if any
    let mut before: Option<f64> = None;
    let mut k = 0;
    while k < scan.len() {
        match scan.reading(k) {
            Reading::Valid(d) => {
                before = Some(d);
                k += 1;
            }
            Reading::Unknown => {
                before = None;
                k += 1;
            }
            Reading::NoReturn => {
                let start = k;
                while k < scan.len() && scan.reading(k) == Reading::NoReturn {
                    k += 1;
                }
                if let (Some(a), Some(Reading::Valid(b))) = (before, (k < scan.len()).then(|| scan.reading(k))) {
                    if k - start <= laser::MAX_LOST_RETURNS
                        && a < inside
                        && b < inside
                        && (a - b).abs() <= error.at(a) + error.at(b)
                    {
                        count += 1;
                    }
                }
                before = None;
            }
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::{pose, ScanGeometry};
    use map::Wall;

    /// A 181-beam, 180-degree scan with 10 m of range.
    fn geometry() -> ScanGeometry {
        ScanGeometry::centred(181, 180f64.to_radians(), 10.0)
    }

    fn dropouts(ranges: &[f32]) -> usize {
        surface_dropouts(&ScanView { geometry: geometry(), ranges }, &ErrorModel::default())
    }

    #[test]
    fn a_lost_return_between_two_readings_of_one_surface_is_a_surface_dropout() {
        let mut r = vec![3.0f32; 181];
        r[50] = 10.0;
        r[100] = 10.0;
        r[101] = 10.0;
        assert_eq!(dropouts(&r), 2);
    }

    #[test]
    fn an_opening_a_range_jump_the_range_edge_or_an_error_code_is_no_surface_dropout() {
        // three in a row: an opening as much as a lost return
        let mut r = vec![3.0f32; 181];
        r[50..53].fill(10.0);
        assert_eq!(dropouts(&r), 0);
        // the two sides at different ranges: seen past an edge
        let mut r = vec![3.0f32; 181];
        r[50] = 10.0;
        r[51..].fill(4.0);
        assert_eq!(dropouts(&r), 0);
        // a wall near the end of the range: noise alone takes readings past it
        let mut r = vec![9.5f32; 181];
        r[50] = 10.0;
        assert_eq!(dropouts(&r), 0);
        // an error code beside it: nothing is known on that side
        let mut r = vec![3.0f32; 181];
        r[50] = 10.0;
        r[51] = 0.0;
        assert_eq!(dropouts(&r), 0);
        // a scan that starts or ends with missing returns
        let mut r = vec![3.0f32; 181];
        r[0] = 10.0;
        r[180] = 10.0;
        assert_eq!(dropouts(&r), 0);
    }

    /// A wall 3 m ahead across the whole scan, seen from the origin, with `lost` beams reading
    /// no return: the true pose's cost with and without skipping missing returns.
    fn wall_cost(lost: &[usize], skip: bool) -> Cost {
        let g = geometry();
        let wall = Wall::new(3.0, -100.0, 3.0, 100.0);
        let caster = RayCaster::new(&[wall]);
        let mut ranges: Vec<f32> = (0..181).map(|i| (3.0 / g.angle(i).cos()).min(9.0) as f32).collect();
        for &i in lost {
            ranges[i] = 10.0;
        }
        cost_at_origin(&ranges, &caster, &CostConfig { skip_no_returns: skip, ..CostConfig::default() })
    }

    /// A wall 3 m ahead ending at 20 degrees left, a far wall 8 m ahead behind it; `past` beams
    /// from the last that meets the near wall read the far one instead. One beam past the end
    /// is the right pose a hair off: it is not seen through the wall. A run of them is a
    /// wall's end misplaced: each is, the last too. The cost is the same either way, and with
    /// `edge_step` at 0 every such beam is seen through.
    #[test]
    fn a_beam_past_a_wall_end_is_not_seen_through_it_but_a_run_of_them_is() {
        let g = geometry();
        let end = 3.0 * 20.5f64.to_radians().tan();
        let caster = RayCaster::new(&[Wall::new(3.0, -100.0, 3.0, end), Wall::new(8.0, -100.0, 8.0, 100.0)]);
        let near = |i: usize| g.angle(i) < 20.5f64.to_radians();
        let last = (0..181).filter(|&i| near(i)).max().unwrap_or(0);
        let through_of = |past: usize, cfg: &CostConfig| {
            let ranges: Vec<f32> = (0..181)
                .map(|i| {
                    let a = g.angle(i);
                    let d = if near(i) && i + past <= last { 3.0 / a.cos() } else { 8.0 / a.cos() };
                    d.min(10.0) as f32
                })
                .collect();
            let c = cost_at_origin(&ranges, &caster, cfg);
            ((c.through * f64::from(c.beams)).round() as usize, c.value)
        };
        let on = CostConfig::default();
        let off = CostConfig { edge_step: 0.0, ..on };
        assert!(g.angle_increment <= on.edge_step);
        assert_eq!(through_of(0, &on).0, 0);
        let (one, one_off) = (through_of(1, &on), through_of(1, &off));
        assert_eq!((one.0, one_off.0), (0, 1));
        assert_eq!(one.1, one_off.1);
        assert_eq!(through_of(3, &on).0, 3);
        assert_eq!(through_of(3, &off).0, 3);
    }

    /// The cost of a pose at the origin for `ranges` read with [`geometry`].
    fn cost_at_origin(ranges: &[f32], caster: &RayCaster, cfg: &CostConfig) -> Cost {
        let scan = ScanView { geometry: geometry(), ranges };
        let (mut scratch, mut expected) = (RayScratch::default(), Vec::new());
        cost(&scan, &pose(0.0, 0.0, 0.0), caster, &ErrorModel::default(), cfg, &mut scratch, &mut expected)
    }

    /// The cap of a short reading by how far short of the wall it falls: the full cap when
    /// misaligned (by less than `clutter_min`) or in open floor (beyond 1.5 `clutter_reach`),
    /// the share where furniture stands, linear between.
    #[test]
    fn a_short_reading_costs_less_where_furniture_stands_than_in_open_floor() {
        let cfg = CostConfig::default();
        let (cap, least) = (cfg.front_cap, cfg.clutter_share * cfg.front_cap);
        assert!(least < cap);
        assert_eq!(cfg.front_cap_at(0.0), cap);
        assert_eq!(cfg.front_cap_at(0.19), cap);
        assert_eq!(cfg.front_cap_at(0.2), least);
        assert_eq!(cfg.front_cap_at(cfg.clutter_reach), least);
        let halfway = 1.25 * cfg.clutter_reach;
        assert!((cfg.front_cap_at(halfway) - (least + cap) / 2.0).abs() < 1e-12);
        assert_eq!(cfg.front_cap_at(1.5 * cfg.clutter_reach), cap);
        assert_eq!(cfg.front_cap_at(50.0), cap);
        let off = CostConfig { clutter_share: 1.0, ..cfg };
        for d in [0.0, 0.5, 1.0, 5.0] {
            assert_eq!(off.front_cap_at(d), cap);
        }
    }

    /// A wall 3 m ahead; 21 beams read a box face 0.5 m in front of it, 11 beams a surface
    /// metres short of it, out in open floor, 5 beams a pose 0.1 m off the wall. The box's
    /// beams cost the share of the cap and the rest the cap; with the share at 1, all the cap.
    #[test]
    fn eq7_charges_a_box_against_a_wall_less_than_a_surface_in_open_floor() {
        let g = geometry();
        let caster = RayCaster::new(&[Wall::new(3.0, -100.0, 3.0, 100.0)]);
        // the wall where it lies in range, no return (as the map predicts) beyond
        let mut ranges: Vec<f32> = (0..181).map(|i| (3.0 / g.angle(i).cos()).min(10.0) as f32).collect();
        let (boxed, open, misaligned) = (80..=100, 20..=30, 120..=124);
        for i in boxed.clone() {
            ranges[i] = (2.5 / g.angle(i).cos()) as f32;
        }
        for i in open.clone() {
            ranges[i] = 1.0;
        }
        for i in misaligned.clone() {
            ranges[i] = (2.9 / g.angle(i).cos()) as f32;
        }
        let scan = ScanView { geometry: g, ranges: &ranges };
        let cfg = CostConfig::default();
        let (mut scratch, mut expected) = (RayScratch::default(), Vec::new());
        let mut at = |cfg: &CostConfig| {
            cost(&scan, &pose(0.0, 0.0, 0.0), &caster, &ErrorModel::default(), cfg, &mut scratch, &mut expected)
        };
        let with = at(&cfg);
        let without = at(&CostConfig { clutter_share: 1.0, ..cfg });
        let beams = with.beams as f64;
        // the beams that see the wall itself cost next to nothing; every other beam its cap
        let (n_box, n_open, n_off) = (boxed.count() as f64, open.count() as f64, misaligned.count() as f64);
        let expect_without = cfg.front_cap * (n_box + n_open + n_off) / beams;
        let expect_with = (cfg.clutter_share * cfg.front_cap * n_box + cfg.front_cap * (n_open + n_off)) / beams;
        assert!((without.value - expect_without).abs() < 0.01, "{without:?}, expected {expect_without}");
        assert!((with.value - expect_with).abs() < 0.01, "{with:?}, expected {expect_with}");
        // agreement is judged as before: the box is neither an inlier nor seen through
        assert_eq!((with.inliers, with.through), (without.inliers, without.through));
    }

    #[test]
    fn the_incidence_comes_from_the_expected_ranges_of_neighbouring_beams() {
        // the wall x = 2 seen at 0.5-degree steps: r = 2 / cos(phi), incidence phi
        let step = 0.5f64.to_radians();
        let expected: Vec<f64> = (0..100).map(|i| 2.0 / (i as f64 * step).cos()).collect();
        for k in [1, 40, 98] {
            let phi = k as f64 * step;
            assert!((incidence_secant_sq(&expected, k, step).sqrt() - 1.0 / phi.cos()).abs() < 0.02, "beam {k}");
        }
        // a jump to another wall on one side: the other side gives the incidence
        let mut jump = expected.clone();
        jump[41..].iter_mut().for_each(|r| *r += 3.0);
        assert!((incidence_secant_sq(&jump, 40, step).sqrt() - 1.0 / (40.0 * step).cos()).abs() < 0.02);
    }

    #[test]
    fn beams_grazing_a_wall_drawn_off_its_place_cost_less_but_still_count_as_through() {
        // the wall y = 1 drawn 15 cm short of where the sensor sees it (y = 1.15), in a map
        // that states 10 cm of accuracy: beams at a few degrees from it read tens of
        // centimetres past the drawn wall
        let g = geometry();
        let caster = RayCaster::new(&[Wall::new(0.0, 1.0, 20.0, 1.0)]);
        let ranges: Vec<f32> =
            (0..181).map(|i| g.angle(i).sin()).map(|s| if s > 0.06 { (1.15 / s) as f32 } else { 0.0 }).collect();
        let at = |grazing_cap: f64| {
            cost_at_origin(&ranges, &caster, &CostConfig { sigma_floor: 0.1, grazing_cap, ..CostConfig::default() })
        };
        let (plain, along) = (at(1.0), at(3.0));
        assert!(plain.through > 0.05, "{plain:?}");
        assert!(along.value < 0.8 * plain.value, "{along:?} vs {plain:?}");
        assert_eq!((along.inliers, along.through), (plain.inliers, plain.through));
    }

    #[test]
    fn a_missing_return_where_the_map_has_a_wall_sees_through_it_unless_skipped() {
        let lost = [80, 90, 100];
        let all = wall_cost(&[], false);
        let counted = wall_cost(&lost, false);
        let skipped = wall_cost(&lost, true);
        assert!(all.through == 0.0 && all.value < 1.0, "{all:?}");
        // each lost beam costs the through-wall cap and counts as seeing through
        assert_eq!(counted.beams, all.beams);
        assert!((counted.through - 3.0 / f64::from(counted.beams)).abs() < 1e-12, "{counted:?}");
        assert!(counted.value > all.value + 3.0 * 11.0 / f64::from(all.beams), "{counted:?} vs {all:?}");
        // skipped, they are as an error code: not costed at all
        assert_eq!(skipped.beams, all.beams - 3);
        assert_eq!(skipped.through, 0.0);
        assert!((skipped.value - all.value).abs() < 0.05, "{skipped:?} vs {all:?}");
    }

    /// A pose stopped by [`cost_below`] costs more than the bound by [`cost`]; one not stopped
    /// gets exactly [`cost`]'s result. A 60 m reach in a 1000-wall office makes the sparse casts
    /// march, so poses are stopped part way.
    #[test]
    fn a_pose_stopped_early_costs_more_than_the_bound_and_the_others_cost_the_same() {
        let map = worlds::office_with_walls(3, 1000);
        let caster = RayCaster::new(&map.walls);
        let g = ScanGeometry::centred(361, 180f64.to_radians(), 60.0);
        let (lo, hi) = map::map::bounds_of(&map.walls);
        let truth = pose(lo.x + 0.37 * (hi.x - lo.x), lo.y + 0.41 * (hi.y - lo.y), 0.3);
        let (mut scratch, mut expected) = (RayScratch::default(), Vec::new());
        caster.cast(&truth, &g, 361, 1, &mut scratch, &mut expected);
        let ranges: Vec<f32> =
            expected.iter().enumerate().map(|(i, &d)| (d.min(60.0) + 0.01 * ((i % 5) as f64 - 2.0)) as f32).collect();
        let scan = ScanView { geometry: g, ranges: &ranges };
        let cfg = CostConfig { stride: 11, sigma_floor: 0.08, ..CostConfig::default() };
        let e = ErrorModel::default();
        let poses: Vec<Pose> = (0..40)
            .map(|k| {
                let k = k as f64;
                pose(
                    truth.translation.x + 0.7 * (k * 0.61).sin() * k / 10.0,
                    truth.translation.y + 0.5 * (k * 1.3).cos(),
                    0.3 + 0.05 * k,
                )
            })
            .collect();
        let mut full: Vec<Cost> =
            poses.iter().map(|p| cost(&scan, p, &caster, &e, &cfg, &mut scratch, &mut expected)).collect();
        let mut values: Vec<f64> = full.iter().map(|c| c.value).collect();
        values.sort_by(f64::total_cmp);
        let bound = values[10];
        let mut stopped = 0;
        for (p, whole) in poses.iter().zip(full.iter_mut()) {
            let below = cost_below(&scan, p, &caster, &e, &cfg, bound, &mut scratch, &mut expected);
            if below.value.is_finite() {
                assert_eq!(below, *whole);
            } else {
                assert!(whole.value > bound, "stopped at {} <= {bound}", whole.value);
                // stopped before its last part
                assert!(below.beams < whole.beams, "{} of {}", below.beams, whole.beams);
                stopped += 1;
            }
        }
        assert!(stopped >= 10, "only {stopped} of 40 poses stopped early");
        // the paper's form counts beams by pose: never stopped
        let paper = CostConfig { kind: CostKind::Paper, ..cfg };
        for p in &poses {
            let whole = cost(&scan, p, &caster, &e, &paper, &mut scratch, &mut expected);
            assert_eq!(cost_below(&scan, p, &caster, &e, &paper, 0.0, &mut scratch, &mut expected), whole);
        }
    }
}
