//! Localization parameters set by name (`--set KEY=VALUE`), after [`segment::settings`]: one
//! vocabulary for `gema2 locate` and the pipeline's `localize` stage.

use crate::gema2::Gema2Config;
use crate::localizer::LocalizerConfig;
use crate::CostKind;
use segment::{SegmenterConfig, Setting, SettingError};

impl LocalizerConfig {
    /// The keys [`set`](Self::set) knows.
    pub const SETTINGS: &'static [&'static str] = &[
        "thorough (1: widen every search budget, for when time is no object)",
        "corners",
        "screen_points",
        "prescreen_step",
        "prescreened",
        "screen_cap",
        "screen_behind (1: off)",
        "screen_open (1: off)",
        "screen_long_line",
        "screened",
        "refined",
        "refine_points",
        "refine_iterations",
        "polish_points (0: no polish)",
        "polish_margin",
        "polish_iterations",
        "first_corners (0: no first look)",
        "first_prescreened",
        "first_screened",
        "first_refined",
        "first_inliers",
        "first_through",
        "coarse_beams",
        "coarse_sigma",
        "sparse_beams",
        "sparse_kept",
        "arm_slack",
        "map_sigma (a floor on the map's accuracy)",
        "cost_stride",
        "front_cap",
        "through_cap",
        "grazing_cap (1: off)",
        "clutter_share (1: off)",
        "clutter_min",
        "clutter_reach",
        "paper_cost (1: eq. 7 as printed)",
        "surface_dropouts (0: never skip missing returns)",
        "inside_only (0: also make hypotheses outside a closed outline)",
        "ambiguity",
        "cornerless_tie",
        "min_inliers",
        "max_through",
        "max_through_approximate (for maps with a sigma of 5 cm or more)",
        "front_cap_approximate (for maps with a sigma of 5 cm or more)",
        "clutter_share_approximate (for maps with a sigma of 5 cm or more; 1: off)",
        "max_through_ok",
        "track (metres; 0: always global)",
        "slide_lines",
        "slide_min_length",
        "slide_min_wall",
        "slide_step",
        "slide_slack",
        "slide_shorter (a fraction of the line's length; above 1: off)",
        "slide_screened",
        "slide_max_poses",
        "slide_sigma_deg",
        "slide_loose_sigma_deg (at most slide_sigma_deg: no loose slide)",
        "slide_loose_lines (0: no loose slide)",
        "slide_min_inliers_ok",
        "escalate_through (a fraction of the beams; 1: never search wider)",
        "escalate_min_beams",
        "grid_headings (0: no grid search)",
        "grid_step",
        "grid_max_poses",
        "grid_prescreened",
        "grid_screened",
        "error_constant",
        "error_proportional",
    ];

    /// Applies `s` when it names a localization parameter: `Ok(true)`; `Ok(false)` when it
    /// names none.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<bool, SettingError> {
        match s.key {
            "thorough" => {
                if s.switch() {
                    *self = self.thorough();
                }
            }
            "corners" => self.corners_tried = s.count()?,
            "screen_points" => self.screen_points = s.count()?,
            "prescreen_step" => self.prescreen_step = s.step()?,
            "prescreened" => self.prescreened = s.count()?,
            "screen_cap" => self.screen_cap = s.positive()?,
            "screen_behind" => self.screen_behind = s.within(1.0, f64::INFINITY, "at least 1 (1: off)")?,
            "screen_open" => self.screen_open = s.within(1.0, f64::INFINITY, "at least 1 (1: off)")?,
            "screen_long_line" => self.screen_long_line = s.non_negative()?,
            "screened" => self.screened = s.count()?,
            "refined" => self.refined = s.count()?,
            "refine_points" => self.refine_points = s.count()?,
            "refine_iterations" => self.refine.iterations = s.count()?,
            "polish_points" => self.polish_points = s.count()?,
            "polish_margin" => self.polish_margin = s.non_negative()?,
            "polish_iterations" => self.polish_iterations = s.count()?,
            "first_corners" => self.first_look.corners = s.count()?,
            "first_prescreened" => self.first_look.prescreened = s.count()?,
            "first_screened" => self.first_look.screened = s.count()?,
            "first_refined" => self.first_look.refined = s.count()?,
            "first_inliers" => self.first_look.min_inliers = s.fraction()?,
            "first_through" => self.first_look.max_through = s.fraction()?,
            "coarse_beams" => self.coarse_beams = s.count()?,
            "coarse_sigma" => self.coarse_sigma = s.positive()?,
            "sparse_beams" => self.sparse_beams = s.count()?,
            "sparse_kept" => self.sparse_kept = s.count()?,
            "arm_slack" => self.arm_slack = s.non_negative()?,
            "map_sigma" => self.cost.sigma_floor = s.non_negative()?,
            "cost_stride" => self.cost.stride = s.step()?,
            "front_cap" => self.cost.front_cap = s.non_negative()?,
            "through_cap" => self.cost.through_cap = s.non_negative()?,
            "grazing_cap" => self.cost.grazing_cap = s.within(1.0, f64::INFINITY, "at least 1 (1: off)")?,
            "clutter_share" => self.cost.clutter_share = s.within(0.0, 1.0, "from 0 to 1 (1: off)")?,
            "clutter_min" => self.cost.clutter_min = s.non_negative()?,
            "clutter_reach" => self.cost.clutter_reach = s.within(0.0, 1.3, "from 0 to 1.3 metres")?,
            "paper_cost" => self.cost.kind = if s.switch() { CostKind::Paper } else { CostKind::OneSided },
            "surface_dropouts" => self.surface_dropouts = s.count()?,
            "inside_only" => self.inside_only = s.switch(),
            "ambiguity" => self.ambiguity_margin = s.non_negative()?,
            "cornerless_tie" => self.cornerless_tie = s.non_negative()?,
            "min_inliers" => self.min_inliers = s.fraction()?,
            "max_through" => self.max_through = s.fraction()?,
            "max_through_approximate" => self.max_through_approximate = s.fraction()?,
            "front_cap_approximate" => self.front_cap_approximate = s.non_negative()?,
            "clutter_share_approximate" => {
                self.clutter_share_approximate = s.within(0.0, 1.0, "from 0 to 1 (1: off)")?
            }
            "max_through_ok" => self.max_through_ok = s.fraction()?,
            "track" => self.track_radius = Some(s.non_negative()?).filter(|&r| r > 0.0),
            "slide_lines" => self.slide.lines = s.count()?,
            "slide_min_length" => self.slide.min_length = s.non_negative()?,
            "slide_min_wall" => self.slide.min_wall = s.non_negative()?,
            "slide_step" => self.slide.step = s.positive()?,
            "slide_slack" => self.slide.slack = s.non_negative()?,
            "slide_shorter" => self.slide.shorter_walls = s.non_negative()?,
            "slide_screened" => self.slide.screened = s.count()?,
            "slide_max_poses" => self.slide.max_poses = s.count()?,
            "slide_sigma_deg" => self.slide.max_direction_sigma = s.degrees()?,
            "slide_loose_sigma_deg" => self.slide.loose_direction_sigma = s.degrees()?,
            "slide_loose_lines" => self.slide.loose_lines = s.count()?,
            "slide_min_inliers_ok" => self.slide.min_inliers_ok = s.fraction()?,
            "escalate_through" => self.escalate_through = s.fraction()?,
            "escalate_min_beams" => self.escalate_min_beams = s.count()?,
            "grid_headings" => self.grid.headings = s.count()?,
            "grid_step" => self.grid.step = s.positive()?,
            "grid_max_poses" => self.grid.max_poses = s.count()?,
            "grid_prescreened" => self.grid.prescreened = s.count()?,
            "grid_screened" => self.grid.screened = s.count()?,
            "error_constant" => self.error.constant = s.positive()?,
            "error_proportional" => self.error.proportional = s.non_negative()?,
            _ => return Ok(false),
        }
        Ok(true)
    }
}

impl Gema2Config {
    /// The map-corner keys [`set`](Self::set) knows besides the segmenter's and localizer's.
    pub const MAP_SETTINGS: &'static [&'static str] = &["map_reach", "wall_ends (0 or 1)"];

    /// Every key [`set`](Self::set) knows, with what a value means where that is not plain.
    pub fn settings() -> Vec<&'static str> {
        let mut all: Vec<&str> = Vec::new();
        for &k in SegmenterConfig::SETTINGS.iter().chain(LocalizerConfig::SETTINGS).chain(Self::MAP_SETTINGS) {
            if !all.contains(&k) {
                all.push(k);
            }
        }
        all
    }

    /// Applies `s` to every configuration it concerns: a key shared by segmentation and
    /// localization (the error model, `wall_ends`) is set in both, so the stages agree.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<(), SettingError> {
        let mut known = self.segmenter.set(s)?;
        known |= self.localizer.set(s)?;
        match s.key {
            "map_reach" => self.map_corners.reach = s.non_negative()?,
            "wall_ends" => self.map_corners.wall_ends = s.switch(),
            _ if known => {}
            _ => return Err(SettingError::Unknown { key: s.key.to_string(), known: Self::settings() }),
        }
        Ok(())
    }

    /// Applies every `KEY=VALUE` of `settings`, or none of them when one is malformed or
    /// unknown.
    pub fn apply<S: AsRef<str>>(&mut self, settings: &[S]) -> Result<(), SettingError> {
        let mut c = *self;
        for kv in settings {
            c.set(&Setting::parse(kv.as_ref())?)?;
        }
        *self = c;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shared_setting_reaches_every_stage_that_uses_it() {
        let mut c = Gema2Config::default();
        c.apply(&["error_constant=0.05", "wall_ends=0", "screened=100", "map_reach=2", "track=3"]).unwrap();
        assert_eq!(c.segmenter.error.constant, 0.05);
        assert_eq!(c.localizer.error.constant, 0.05);
        assert!(!c.segmenter.ends.enabled && !c.map_corners.wall_ends);
        assert_eq!(c.localizer.screened, 100);
        assert_eq!(c.map_corners.reach, 2.0);
        assert_eq!(c.localizer.track_radius, Some(3.0));
    }

    #[test]
    fn unknown_or_malformed_settings_change_nothing() {
        let mut c = Gema2Config::default();
        let before = format!("{c:?}");
        let err = c.apply(&["screened=100", "screend=5"]).unwrap_err();
        assert!(err.to_string().contains("\"screend\""), "{err}");
        assert!(err.to_string().contains("screened") && err.to_string().contains("merge_angle"), "{err}");
        assert!(c.apply(&["screened=100", "refined=-1"]).is_err());
        assert!(c.apply(&["screened=100", "front_cap=NaN"]).is_err());
        assert_eq!(format!("{c:?}"), before);
    }

    #[test]
    fn a_value_outside_its_parameter_s_range_is_refused() {
        let mut c = Gema2Config::default();
        let before = format!("{c:?}");
        for bad in [
            "front_cap=-3",
            "screen_cap=0",
            "first_inliers=2",
            "max_through=-0.1",
            "slide_step=0",
            "slide_sigma_deg=400",
            "grazing_cap=0.5",
            "cost_stride=0",
            "prescreen_step=0",
            "track=-1",
            "map_reach=-1",
            "error_constant=0",
        ] {
            let err = c.apply(&[bad]).unwrap_err();
            assert!(matches!(err, SettingError::OutOfRange { .. }), "{bad}: {err}");
            assert!(err.to_string().contains(bad.split('=').next().unwrap_or(bad)), "{err}");
        }
        assert_eq!(format!("{c:?}"), before);
        c.apply(&["track=0", "grazing_cap=1", "min_inliers=0", "max_through_ok=1"]).unwrap();
        assert_eq!(c.localizer.track_radius, None);
    }

    #[test]
    fn thorough_widens_the_search_and_later_settings_still_apply() {
        let (plain, mut c) = (Gema2Config::default(), Gema2Config::default());
        c.apply(&["thorough=1", "refined=30"]).unwrap();
        let (t, p) = (&c.localizer, &plain.localizer);
        assert!(t.prescreened > p.prescreened && t.sparse_kept > p.sparse_kept);
        assert!(t.slide.lines > p.slide.lines && t.slide.min_length <= p.slide.min_length);
        assert!(t.slide.min_wall < p.slide.min_wall);
        assert!(t.slide.max_poses > p.slide.max_poses && t.slide.screened > p.slide.screened);
        assert_eq!(t.refined, 30);
        // thresholds and the cost are left as they were
        assert_eq!((t.cost, t.max_through_ok, t.min_inliers), (p.cost, p.max_through_ok, p.min_inliers));
        let mut off = Gema2Config::default();
        off.apply(&["thorough=0"]).unwrap();
        assert_eq!(format!("{off:?}"), format!("{plain:?}"));
    }

    #[test]
    fn every_listed_key_is_accepted() {
        for listed in Gema2Config::settings() {
            let key = listed.split(' ').next().unwrap_or(listed);
            let mut c = Gema2Config::default();
            assert!(c.apply(&[format!("{key}=1")]).is_ok(), "{key}");
        }
    }
}
