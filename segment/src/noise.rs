//! How noisy a scan really is, measured on the scan itself.
//!
//! e(d) (section 3) is a calibration: the paper measured 2 cm for its sensor. A sensor noisier
//! than its configured e(d) breaks two things at once: line visibility shatters walls into
//! fragments (docs/how-it-works.md, "Where the paper falls short", point 4), and the cost function counts the right pose's beams as
//! outliers and as seeing through walls, so the right pose is reported `failed`. With e(d)
//! calibrated for 1 cm + 0.5 % of range, simulated scans at twice that noise were located
//! right 95 % of the time but all save 11 % of them were `failed`.
//!
//! Three beams a step apart that meet one straight wall read ranges a, b, c with
//! 1/a + 1/c = 2 cos(step) / b exactly (the inverse range along a line is a sinusoid of the
//! beam angle), whatever the incidence and the beam spacing. Scaled by b^2, the amount by which
//! a triple misses that is, to first order, the second difference of the readings' noise, with
//! standard deviation sqrt(6) sigma; only depth jumps, corners and curved surfaces add to it,
//! a few percent of the beams. (The ranges' plain second difference `d[i-1] - 2 d[i] + d[i+1]`
//! is not zero on a wall met at grazing incidence: a noiseless corridor seen by a 1-degree
//! scanner reads 0.25 with it.) The median of |miss| / (sqrt(6) e(d) / 3) therefore measures
//! the ratio of the real noise to the configured one. Jumps move the median
//! only a little while they are few: each spoils three triples, and with a tenth of the
//! triples spoiled the ratio reads about 1.13 for 1 (a quarter spoiled: 1.45).

use crate::sample::ErrorModel;
use laser::{Reading, ScanView};

/// Fewest triples of consecutive valid readings for a [`noise_ratio`]: below this the median
/// is too uncertain to act on.
pub const MIN_TRIPLES: usize = 30;

/// The median absolute value of a standard normal variable.
const NORMAL_MAD: f64 = 0.674_489_75;

/// The scan's noise relative to `error`'s: the robust standard deviation of how far each triple
/// of consecutive valid ranges misses being collinear (see the module docs), each divided by
/// sqrt(6) e(d) / 3 at its range.
/// About 1 for a sensor that matches its e(d) (less for a quieter one); `None` with fewer than
/// [`MIN_TRIPLES`] triples. `scratch` is reusable space.
pub fn noise_ratio(scan: &ScanView<'_>, error: &ErrorModel, scratch: &mut Vec<f64>) -> Option<f64> {
    scratch.clear();
    let valid = |i: usize| match scan.reading(i) {
        Reading::Valid(d) => Some(d),
        _ => None,
    };
    // the collinearity miss of the module docs
    let two_cos = 2.0 * scan.geometry.angle_increment.cos();
    let mut window = [None; 3];
    for i in 0..scan.len() {
        window = [window[1], window[2], valid(i)];
        if let [Some(a), Some(b), Some(c)] = window {
            let sigma = error.at(b) / 3.0;
            if sigma > 0.0 && a > 0.0 && b > 0.0 && c > 0.0 {
                let miss = b * b * (1.0 / a + 1.0 / c) - two_cos * b;
                scratch.push((miss / (6f64.sqrt() * sigma)).abs());
            }
        }
    }
    if scratch.len() < MIN_TRIPLES {
        return None;
    }
    let mid = scratch.len() / 2;
    let (_, median, _) = scratch.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*median / NORMAL_MAD)
}

/// A widening factor as received from elsewhere (a message, a caller's segmentation), made
/// safe to multiply e(d) by: below 1 or not finite is no measurement, and means 1.
pub fn usable_scale(scale: f64) -> f64 {
    if scale.is_finite() && scale > 1.0 {
        scale
    } else {
        1.0
    }
}

/// How much to widen e(d) for this scan: its [`noise_ratio`] when that exceeds `tolerance`,
/// else 1. `tolerance` keeps a sensor that matches its calibration on its calibrated e(d):
/// the ratio of such a sensor scatters from scan to scan (0.9-1.2 on the simulated logs), and
/// up to 1.25 times too narrow an e(d) still counts under 1 % of the right pose's beams as
/// seeing through walls. A `tolerance` of 0 or less, or infinite, never widens.
pub fn noise_scale(scan: &ScanView<'_>, error: &ErrorModel, tolerance: f64, scratch: &mut Vec<f64>) -> f64 {
    if !(tolerance > 0.0 && tolerance.is_finite()) {
        return 1.0;
    }
    match noise_ratio(scan, error, scratch) {
        Some(ratio) if ratio > tolerance => usable_scale(ratio),
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inference::tests_support::room_ranges;
    use laser::ScanGeometry;
    use proptest::prelude::*;

    /// Standard normal deviates from a seed (xorshift and Box-Muller): tests need no RNG crate.
    /// The seed is mixed first (splitmix64): xorshift started from a small seed gives
    /// correlated first outputs.
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let mut x = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x = (x ^ (x >> 31)).max(1);
        let mut uniform = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos()).collect()
    }

    /// A room seen by the URG-04LX with noise of `k` times the model's sigma = e(d) / 3.
    fn noisy_room(e: &ErrorModel, k: f64, seed: u64) -> (ScanGeometry, Vec<f32>) {
        let g = ScanGeometry::urg04lx();
        let clean = room_ranges(&g, 682, &[(-1.0, -1.5), (4.0, -2.0), (4.5, 2.5), (-1.5, 2.0)]);
        let noise = normals(seed, clean.len());
        let ranges = clean.iter().zip(&noise).map(|(&d, z)| (d as f64 + k * z * e.at(d as f64) / 3.0) as f32).collect();
        (g, ranges)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The ratio recovers how much noisier than its model a scan is, corners and all. One
        /// scan's ratio scatters by 5.4 % (standard deviation over 2000 seeds, no bias, at 0.5,
        /// 1 and 4 times the noise), so a single scan checked against 20 % would fail about one
        /// case in ten thousand on luck alone; the mean of four scans scatters by half that.
        #[test]
        fn the_ratio_measures_the_noise_relative_to_the_model(k in 0.5f64..4.0, seed in 1u64..1_000_000) {
            let e = ErrorModel::default();
            let ratio = (0..4)
                .map(|i| {
                    let (g, ranges) = noisy_room(&e, k, 4 * seed + i);
                    noise_ratio(&ScanView { geometry: g, ranges: &ranges }, &e, &mut Vec::new()).unwrap()
                })
                .sum::<f64>()
                / 4.0;
            prop_assert!((ratio / k - 1.0).abs() < 0.2, "noise {k} times the model's measured as {ratio}");
        }
    }

    #[test]
    fn depth_jumps_and_invalid_readings_do_not_move_the_ratio() {
        let e = ErrorModel::default();
        let (g, mut ranges) = noisy_room(&e, 1.0, 7);
        let plain = noise_ratio(&ScanView { geometry: g, ranges: &ranges }, &e, &mut Vec::new()).unwrap();
        // every 30th beam a reading 1 m short (a jump in and out: three triples each, 10 % of
        // them, a cluttered scan), every 40th invalid
        for (i, r) in ranges.iter_mut().enumerate() {
            if i % 30 == 0 {
                *r -= 1.0;
            }
            if i % 40 == 0 {
                *r = f32::NAN;
            }
        }
        let jumpy = noise_ratio(&ScanView { geometry: g, ranges: &ranges }, &e, &mut Vec::new()).unwrap();
        assert!((0.8..1.25).contains(&plain), "{plain}");
        assert!((jumpy / plain - 1.0).abs() < 0.2, "{plain} -> {jumpy}");
    }

    /// A corridor seen by a 1-degree scanner: most beams meet its walls at grazing incidence,
    /// where the ranges' plain second differences are large without any noise. Noiseless, it
    /// must read as noiseless.
    #[test]
    fn walls_at_grazing_incidence_are_not_read_as_noise() {
        let g = ScanGeometry {
            angle_min: -std::f64::consts::FRAC_PI_4,
            angle_increment: 1f64.to_radians(),
            range_min: 0.02,
            range_max: 30.0,
        };
        // walls 1 m either side, beams within 45 degrees of its axis (plain second differences
        // read 0.25 here)
        let ranges: Vec<f32> = (0..91)
            .map(|i| {
                let a = g.angle_min + i as f64 * g.angle_increment;
                (1.0 / a.sin().abs()).min(30.0) as f32
            })
            .collect();
        let ratio = noise_ratio(&ScanView { geometry: g, ranges: &ranges }, &ErrorModel::default(), &mut Vec::new());
        assert!(ratio.unwrap() < 0.05, "{ratio:?}");
    }

    #[test]
    fn a_received_scale_is_used_only_when_it_widens() {
        assert_eq!(usable_scale(1.7), 1.7);
        for bad in [0.0, 0.5, -3.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(usable_scale(bad), 1.0, "{bad}");
        }
    }

    #[test]
    fn too_few_readings_give_no_ratio_and_no_widening() {
        let e = ErrorModel::default();
        let (g, mut ranges) = noisy_room(&e, 3.0, 3);
        for r in ranges.iter_mut().skip(MIN_TRIPLES + 1) {
            *r = f32::NAN;
        }
        let scan = ScanView { geometry: g, ranges: &ranges };
        assert_eq!(noise_ratio(&scan, &e, &mut Vec::new()), None);
        assert_eq!(noise_scale(&scan, &e, 1.25, &mut Vec::new()), 1.0);
    }

    #[test]
    fn only_a_scan_noisier_than_the_tolerance_widens_e() {
        let e = ErrorModel::default();
        let mut scratch = Vec::new();
        let (g, calibrated) = noisy_room(&e, 1.0, 11);
        let (_, noisy) = noisy_room(&e, 2.5, 11);
        let calibrated = ScanView { geometry: g, ranges: &calibrated };
        let noisy = ScanView { geometry: g, ranges: &noisy };
        assert_eq!(noise_scale(&calibrated, &e, 1.25, &mut scratch), 1.0);
        let widened = noise_scale(&noisy, &e, 1.25, &mut scratch);
        assert!((2.0..3.0).contains(&widened), "{widened}");
        // off: a tolerance of 0, or an infinite one
        assert_eq!(noise_scale(&noisy, &e, 0.0, &mut scratch), 1.0);
        assert_eq!(noise_scale(&noisy, &e, f64::INFINITY, &mut scratch), 1.0);
    }
}
