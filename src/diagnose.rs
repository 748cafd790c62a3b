//! Where a scan's localization went wrong, judged against the truth: the stage that lost the
//! right pose. Used by `gema2 locate --diagnose` to direct work at the costliest failure.

use crate::report::{SUCCESS_HEADING_DEG, SUCCESS_POSITION};
use laser::Pose;
use localize::{same_pose, Localization, Status};
use segment::Segmentation;
use std::collections::BTreeMap;

/// The first stage at which the right pose was lost.
pub fn classify(
    seg: &Segmentation,
    loc: &Localization,
    truth: &Pose,
    model: &localize::MapModel,
    config: &localize::LocalizerConfig,
) -> &'static str {
    let near = |p: &Pose| same_pose(p, truth, SUCCESS_POSITION, SUCCESS_HEADING_DEG.to_radians());
    let best_right = loc.hypotheses.first().is_some_and(|h| near(&h.pose));
    if best_right {
        return match loc.status {
            Status::Ok => "right, ok",
            Status::Ambiguous => "right, ambiguous",
            Status::Failed => "right, but failed (too few beams agree, too many see through, or a tie along its wall)",
        };
    }
    if seg.corners.is_empty() {
        return "no scan corner";
    }
    match loc.all_candidates.iter().position(|c| near(&c.0)) {
        None if right_match_exists(seg, truth, model, config) => "right match dropped by the first screening pass",
        None => "no scan corner matches a map corner at the truth",
        Some(rank) if !loc.hypotheses.iter().any(|h| near(&h.pose)) => {
            if rank < 32 {
                "candidate lost in the coarse cost or refinement"
            } else {
                "candidate screened out"
            }
        }
        Some(_) => "right pose out-ranked by the cost",
    }
}

/// Whether one of the scan corners the search matches, with one of the map corners it is
/// matched against, gives a pose near the truth.
fn right_match_exists(
    seg: &Segmentation,
    truth: &Pose,
    model: &localize::MapModel,
    cfg: &localize::LocalizerConfig,
) -> bool {
    seg.corners.iter().take(cfg.corners_tried).any(|c| {
        model.corners.similar(c.inner_angle, cfg.angle_tolerance(c)).iter().any(|m| {
            localize::matching::arms_fit(c, m, cfg.arm_slack)
                && same_pose(
                    &localize::pose_from_corners(c, m),
                    truth,
                    SUCCESS_POSITION,
                    SUCCESS_HEADING_DEG.to_radians(),
                )
        })
    })
}

#[derive(Default)]
pub struct Diagnosis {
    counts: BTreeMap<&'static str, usize>,
}

impl Diagnosis {
    pub fn add(&mut self, what: &'static str) {
        *self.counts.entry(what).or_default() += 1;
    }

    /// Whether no scan was diagnosed (none had a true pose).
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    pub fn render(&self) -> String {
        self.counts.iter().map(|(k, v)| format!("  {v:5}  {k}\n")).collect()
    }
}

/// Prints each scan corner, placed in the map by the truth, beside the nearest map corner.
pub fn dump(seg: &Segmentation, loc: &Localization, truth: &Pose, model: &localize::MapModel) {
    let near = |p: &Pose, d: f64, a: f64| same_pose(p, truth, d, a.to_radians());
    let loose = loc.all_candidates.iter().position(|c| near(&c.0, 0.8, 15.0));
    eprintln!(
        "  candidates {} (scores {:.4}..{:.4}; first within 0.8 m / 15 deg: {:?}), lines {}, full search {}, slide search {} (step {:?}), loose slide {}, wider slide {}, grid {}",
        loc.all_candidates.len(),
        loc.all_candidates.iter().map(|c| c.1).fold(f64::INFINITY, f64::min),
        loc.all_candidates.iter().map(|c| c.1).fold(f64::NEG_INFINITY, f64::max),
        loose,
        seg.lines.len(),
        loc.times.full_search(),
        loc.times.slide_search(),
        loc.slide_step,
        loc.times.loose_slide(),
        loc.times.escalated(),
        loc.times.grid_search()
    );
    for (k, h) in loc.hypotheses.iter().take(6).enumerate() {
        eprintln!(
            "  h{k}: cost {:.3} inliers {:.3} through {:.3} beams {} from {} {}",
            h.cost.value,
            h.cost.inliers,
            h.cost.through,
            h.cost.beams,
            match h.scan_corner {
                localize::FROM_SLIDE => "slide".to_string(),
                localize::FROM_GRID => "grid".to_string(),
                c => format!("c{c}"),
            },
            if near(&h.pose, SUCCESS_POSITION, SUCCESS_HEADING_DEG) { "right" } else { "wrong" }
        );
    }
    for (k, c) in seg.corners.iter().take(10).enumerate() {
        let p = truth * c.position;
        let nearest = model
            .corners
            .similar(c.inner_angle, 10f64.to_radians())
            .iter()
            .min_by(|a, b| (a.position - p).norm().total_cmp(&(b.position - p).norm()));
        let wall_dist =
            |q: nalgebra::Point2<f64>| model.map.walls.iter().map(|w| w.closest(q).0).fold(f64::INFINITY, f64::min);
        let ends: Vec<String> = c
            .arms
            .iter()
            .map(|a| format!("{:.2}", wall_dist(truth * (c.position + a.direction * (a.gap + a.length)))))
            .collect();
        eprint!("    corner-wall {:.2} arm-end-wall {:?}", wall_dist(p), ends);
        let theta = laser::pose_theta(truth);
        let o = laser::wrap_angle(c.orientation + theta);
        for m in model.corners.similar(c.inner_angle, 10f64.to_radians()) {
            if (m.position - p).norm() < 0.5 {
                let pose = localize::pose_from_corners(c, m);
                eprint!(
                    " [match: right {} arms_fit {} beta {:.1}]",
                    near(&pose, 0.3, 5.0),
                    localize::matching::arms_fit(c, m, localize::LocalizerConfig::default().arm_slack),
                    m.inner_angle.to_degrees()
                );
            }
        }
        match nearest {
            Some(m) => eprintln!(
                "  c{k}: q {:.2} beta {:6.1} orient {:6.1} arms {:.2}+{:.2}/{:.2}+{:.2} sig {:.2} | map d {:.2} beta {:6.1} orient {:6.1}",
                c.quality, c.inner_angle.to_degrees(), o.to_degrees(), c.arms[0].gap, c.arms[0].length, c.arms[1].gap, c.arms[1].length,
                c.inner_angle_sigma().to_degrees(), (m.position - p).norm(), m.inner_angle.to_degrees(), m.orientation.to_degrees()
            ),
            None => eprintln!("  c{k}: no map corners"),
        }
    }
}

/// Prints how the search judges the true pose ([`localize::Localizer::judge`]), after
/// [`dump`].
pub fn dump_judgement(j: &localize::Judgement, truth: &Pose) {
    let (at, after) = (j.cost, j.refined_cost);
    eprintln!(
        "  truth: prescreen {:.4} screen {:.4}; cost {:.3} inliers {:.3} through {:.3}; refined from it ({:.2} m off): cost {:.3} inliers {:.3} through {:.3}",
        j.prescreen,
        j.screen,
        at.value,
        at.inliers,
        at.through,
        (j.refined.translation.vector - truth.translation.vector).norm(),
        after.value,
        after.inliers,
        after.through
    );
}

/// One scan's segmentation and the map seen from the true pose, as JSON (sensor frame), for
/// plotting.
pub fn scan_json(scan: &laser::LaserScan, seg: &Segmentation, model: &localize::MapModel) -> String {
    let inv = scan.truth.map(|t| t.inverse()).unwrap_or_else(Pose::identity);
    let pts: Vec<String> = seg.samples.iter().map(|s| format!("[{:.4},{:.4}]", s.point().x, s.point().y)).collect();
    let raw: Vec<String> = seg
        .raw_lines
        .iter()
        .map(|l| format!("[{:.4},{:.4},{:.4},{:.4},{}]", l.start.x, l.start.y, l.end.x, l.end.y, l.samples))
        .collect();
    let lines: Vec<String> = seg
        .lines
        .iter()
        .map(|l| format!("[{:.4},{:.4},{:.4},{:.4},{}]", l.start.x, l.start.y, l.end.x, l.end.y, l.samples))
        .collect();
    let corners: Vec<String> = seg
        .corners
        .iter()
        .map(|c| format!("[{:.4},{:.4},{:.2}]", c.position.x, c.position.y, c.inner_angle.to_degrees()))
        .collect();
    let walls: Vec<String> = model
        .map
        .walls
        .iter()
        .map(|w| {
            let (a, b) = (inv * w.a, inv * w.b);
            format!("[{:.4},{:.4},{:.4},{:.4}]", a.x, a.y, b.x, b.y)
        })
        .collect();
    format!(
        "{{\"points\":[{}],\"raw_lines\":[{}],\"lines\":[{}],\"corners\":[{}],\"walls\":[{}]}}",
        pts.join(","),
        raw.join(","),
        lines.join(","),
        corners.join(","),
        walls.join(",")
    )
}
