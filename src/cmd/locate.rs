//! `gema2 locate`: the whole algorithm over a log, offline (no IPC). Writes the CSV of
//! DESIGN.md and prints timing and, when the log holds truth, accuracy.

use crate::report::{Outcome, Summary};
use acquire::{CarmenReader, FlaserLayout};
use anyhow::{Context, Result};
use clap::Args;
use localize::{Gema2, LocalizerConfig, MapModel, Status};
use mapserver::MapCornerConfig;
use segment::SegmenterConfig;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct LocateArgs {
    /// A bundled map's name or a JSON map file.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// CARMEN log (ROBOTLASER1 or FLASER; .gz is fine).
    #[arg(long)]
    pub log: PathBuf,
    /// Locate every K-th laser line...
    #[arg(long, default_value_t = 1)]
    pub every: usize,
    /// ...starting at this one.
    #[arg(long, default_value_t = 0)]
    pub offset: usize,
    /// CSV output (default: none).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Scan corners matched per scan (1 = the paper's single best corner).
    #[arg(long)]
    pub corners: Option<usize>,
    /// Use the paper's plain eq. 7 instead of the one-sided cost.
    #[arg(long)]
    pub paper_cost: bool,
    /// Use the paper's e(d) = 2 cm instead of 3 cm + 1.5 % of range.
    #[arg(long)]
    pub paper_error: bool,
    /// Track: after an ok scan, match only map corners within this radius (metres) of it.
    #[arg(long)]
    pub track: Option<f64>,
    /// With truth in the log: print at which stage each scan's right pose was lost.
    #[arg(long)]
    pub diagnose: bool,
    /// Override a parameter, KEY=VALUE (repeatable): reach, long_reach, long_line, min_arm,
    /// max_direction_sigma (degrees), corners, screen_points, prescreen_step, prescreened,
    /// screen_cap, screened, map_reach, wall_ends (0 or 1), refined, refine_points,
    /// refine_iterations, polish_points (0: no polish), polish_margin, polish_iterations,
    /// first_corners (0: no first look), first_prescreened, first_screened, first_refined,
    /// first_inliers, first_through, coarse_beams, coarse_sigma, sparse_beams, sparse_kept,
    /// arm_slack, map_sigma (a floor on the map's accuracy), cost_stride, front_cap, through_cap,
    /// grazing_cap (1: off), surface_dropouts (0: never skip missing returns), inside_only (0: also
    /// make hypotheses outside a closed outline), ambiguity, cornerless_tie, min_inliers,
    /// max_through, max_through_approximate (for maps with a sigma of 5 cm or more),
    /// max_through_ok, merge_angle (degrees), min_samples, averaging (readings per sample, section
    /// 4.1), noise_tolerance (0: never widen e(d) to a noisier scan's measured noise),
    /// error_constant, error_proportional, slide_lines, slide_min_length, slide_step, slide_slack,
    /// slide_screened, slide_max_poses, slide_sigma_deg, slide_min_inliers_ok.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Write scan N's samples, lines, corners and (true-pose) map as JSON to this folder
    /// (created if missing).
    #[arg(long, num_args = 2, value_names = ["N", "DIR"])]
    pub dump_scan: Vec<String>,
}

/// The segmenter, localizer and map-corner settings of `a`.
pub fn configs(a: &LocateArgs) -> Result<(SegmenterConfig, LocalizerConfig, MapCornerConfig)> {
    let mut seg = SegmenterConfig::default();
    let mut map_corners = MapCornerConfig::default();
    let mut loc = LocalizerConfig::default();
    if let Some(k) = a.corners {
        loc.corners_tried = k.max(1);
    }
    if a.paper_cost {
        loc.cost.kind = localize::CostKind::Paper;
    }
    if a.paper_error {
        seg.error = segment::ErrorModel::PAPER;
        loc.error = segment::ErrorModel::PAPER;
    }
    loc.record_candidates = a.diagnose;
    loc.track_radius = a.track;
    for kv in &a.set {
        let (k, v) = kv.split_once('=').with_context(|| format!("--set {kv}: expected KEY=VALUE"))?;
        let v: f64 = v.parse().with_context(|| format!("--set {kv}: {v:?} is not a number"))?;
        match k {
            "reach" => seg.corner.reach = v,
            "long_reach" => seg.corner.long_reach = v,
            "long_line" => seg.corner.long_line = v,
            "min_arm" => seg.corner.min_arm_length = v,
            "max_direction_sigma" => seg.corner.max_direction_sigma = v.to_radians(),
            "corners" => loc.corners_tried = v as usize,
            "screened" => loc.screened = v as usize,
            "screen_points" => loc.screen_points = v as usize,
            "prescreen_step" => loc.prescreen_step = v as usize,
            "prescreened" => loc.prescreened = v as usize,
            "screen_cap" => loc.screen_cap = v,
            "map_reach" => map_corners.reach = v,
            "wall_ends" => {
                seg.ends.enabled = v != 0.0;
                map_corners.wall_ends = v != 0.0;
            }
            "refined" => loc.refined = v as usize,
            "refine_points" => loc.refine_points = v as usize,
            "refine_iterations" => loc.refine.iterations = v as usize,
            "polish_points" => loc.polish_points = v as usize,
            "polish_margin" => loc.polish_margin = v,
            "polish_iterations" => loc.polish_iterations = v as usize,
            "first_corners" => loc.first_look.corners = v as usize,
            "first_screened" => loc.first_look.screened = v as usize,
            "first_prescreened" => loc.first_look.prescreened = v as usize,
            "first_refined" => loc.first_look.refined = v as usize,
            "first_inliers" => loc.first_look.min_inliers = v,
            "first_through" => loc.first_look.max_through = v,
            "slide_lines" => loc.slide.lines = v as usize,
            "slide_min_length" => loc.slide.min_length = v,
            "slide_step" => loc.slide.step = v,
            "slide_slack" => loc.slide.slack = v,
            "slide_screened" => loc.slide.screened = v as usize,
            "slide_max_poses" => loc.slide.max_poses = v as usize,
            "slide_sigma_deg" => loc.slide.max_direction_sigma = v.to_radians(),
            "slide_min_inliers_ok" => loc.slide.min_inliers_ok = v,
            "coarse_beams" => loc.coarse_beams = v as usize,
            "coarse_sigma" => loc.coarse_sigma = v,
            "sparse_beams" => loc.sparse_beams = v as usize,
            "sparse_kept" => loc.sparse_kept = v as usize,
            "arm_slack" => loc.arm_slack = v,
            "map_sigma" => loc.cost.sigma_floor = v,
            "front_cap" => loc.cost.front_cap = v,
            "cost_stride" => loc.cost.stride = v as usize,
            "through_cap" => loc.cost.through_cap = v,
            "grazing_cap" => loc.cost.grazing_cap = v,
            "surface_dropouts" => loc.surface_dropouts = v as usize,
            "inside_only" => loc.inside_only = v != 0.0,
            "ambiguity" => loc.ambiguity_margin = v,
            "cornerless_tie" => loc.cornerless_tie = v,
            "min_inliers" => loc.min_inliers = v,
            "max_through" => loc.max_through = v,
            "max_through_approximate" => loc.max_through_approximate = v,
            "max_through_ok" => loc.max_through_ok = v,
            "merge_angle" => seg.filter.merge_angle = v.to_radians(),
            "min_samples" => seg.filter.min_samples = v as u32,
            "averaging" => seg.averaging = v as usize,
            "noise_tolerance" => seg.noise_tolerance = v,
            "error_constant" => {
                seg.error.constant = v;
                loc.error.constant = v;
            }
            "error_proportional" => {
                seg.error.proportional = v;
                loc.error.proportional = v;
            }
            _ => anyhow::bail!("--set: unknown parameter {k:?}"),
        }
    }
    Ok((seg, loc, map_corners))
}

pub fn run(a: LocateArgs) -> Result<()> {
    let map = mapserver::load_map(&a.map)?;
    let (seg_cfg, loc_cfg, corner_cfg) = configs(&a)?;
    let model = Arc::new(MapModel::new(map, &corner_cfg));
    let mut gema2 = Gema2::new(Arc::clone(&model), seg_cfg, loc_cfg);
    let reader = CarmenReader::open(&a.log, FlaserLayout::default())?;
    let mut csv = match &a.out {
        Some(p) => {
            let f = std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?;
            let mut w = BufWriter::new(f);
            writeln!(w, "{}", crate::report::CSV_HEADER)?;
            Some(w)
        }
        None => None,
    };
    let mut summary = Summary::default();
    let mut diagnosis = crate::diagnose::Diagnosis::default();
    let mut judge = None;
    for (index, item) in reader.enumerate() {
        let item = item?;
        if a.every == 0 || index % a.every != a.offset % a.every.max(1) {
            continue;
        }
        let scan = &item.scan;
        let start = Instant::now();
        let (seg, loc) = gema2.process(&scan.view());
        let micros = start.elapsed().as_secs_f64() * 1e6;
        if a.dump_scan.len() == 2 && a.dump_scan[0].parse::<usize>().ok() == Some(index) {
            let dir = PathBuf::from(&a.dump_scan[1]);
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            let path = dir.join(format!("scan{index}.json"));
            std::fs::write(&path, crate::diagnose::scan_json(scan, seg, &model))
                .with_context(|| format!("writing {}", path.display()))?;
        }
        if let (true, Some(truth)) = (a.diagnose, scan.truth.as_ref()) {
            let what = crate::diagnose::classify(seg, loc, truth, &model, &loc_cfg);
            if std::env::var_os("GEMA2_DUMP").is_some_and(|v| v.to_str().is_some_and(|v| what.starts_with(v))) {
                eprintln!("scan {index}: {what}");
                crate::diagnose::dump(seg, loc, truth, &model);
                judge = Some(*truth);
            }
            diagnosis.add(what);
        }
        let best = loc.hypotheses.first().filter(|_| loc.status != Status::Failed);
        if let Some(w) = csv.as_mut() {
            let fields = best.map(|h| {
                (
                    h.pose.translation.x,
                    h.pose.translation.y,
                    laser::pose_theta(&h.pose),
                    h.cost.value,
                    h.cost.inliers,
                    h.cost.through,
                )
            });
            let row = crate::report::csv_row(
                index,
                fields,
                loc.status.as_str(),
                micros,
                loc.hypotheses.len(),
                loc.candidates,
            );
            writeln!(w, "{row}")?;
        }
        summary
            .add(Outcome::of(loc.status, best.map(|h| h.pose), scan.truth, micros).with_steps(&seg.times, &loc.times));
        if let Some(truth) = judge.take() {
            crate::diagnose::dump_judgement(&gema2.localizer.judge(&scan.view(), &truth), &truth);
        }
    }
    if let Some(mut w) = csv {
        w.flush()?;
    }
    eprint!("{}", summary.render());
    if a.diagnose {
        eprint!("{}", diagnosis.render());
    }
    Ok(())
}
