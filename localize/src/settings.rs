//! Localization parameters set by name (`--set KEY=VALUE`), after [`segment::settings`]: one
//! vocabulary for `gema2 locate` and the pipeline's `localize` stage.

use crate::gema2::Gema2Config;
use crate::localizer::LocalizerConfig;
use crate::sequential::SequentialConfig;
use crate::CostKind;
use map::MapCornerConfig;
use segment::setting;
use segment::settings::{set_by_table, Range, SettingSpec};
use segment::{SegmenterConfig, Setting, SettingError};

/// One settable key as `gema2 settings` lists it.
#[derive(Clone, Debug, PartialEq)]
pub struct SettingRow {
    /// The stage whose parameter it is: `segment`, `localize`, or `segment, localize` for a
    /// key both take (they must agree on it).
    pub stage: &'static str,
    pub key: &'static str,
    pub default: String,
    pub range: &'static str,
    pub meaning: &'static str,
}

/// The stage of the sequential localizer's keys as `gema2 settings` groups them.
const SEQUENTIAL: &str = "localize, sequential (--sequential, --impl sequential)";

impl LocalizerConfig {
    /// Every localization parameter settable by name.
    pub const SETTINGS: &'static [SettingSpec<LocalizerConfig>] = &[
        SettingSpec {
            key: "thorough",
            range: Range::Switch,
            meaning: "widen every search budget, for when time is no object",
            get: |_| 0.0,
            put: |c, v| {
                if v != 0.0 {
                    *c = c.thorough();
                }
            },
        },
        setting!(
            LocalizerConfig,
            "corners",
            Range::Count,
            "scan corners matched per scan, best first (eq. 4 order)",
            corners_tried
        ),
        setting!(
            LocalizerConfig,
            "screen_points",
            Range::Count,
            "scan points that screen each hypothesis against the distance field",
            screen_points
        ),
        setting!(
            LocalizerConfig,
            "prescreen_step",
            Range::Step,
            "the first screening pass reads one point in this many",
            prescreen_step
        ),
        setting!(
            LocalizerConfig,
            "prescreened",
            Range::Count,
            "candidates kept by the first screening pass",
            prescreened
        ),
        setting!(
            LocalizerConfig,
            "screen_cap",
            Range::Positive,
            "distance from the walls beyond which a screened point is unexplained, metres",
            screen_cap
        ),
        setting!(
            LocalizerConfig,
            "screen_behind",
            Range::Within(1.0, f64::INFINITY, "at least 1 (1: off)"),
            "cost of a screened point behind a closed outline, in caps squared (1: off)",
            screen_behind
        ),
        setting!(
            LocalizerConfig,
            "screen_open",
            Range::Within(1.0, f64::INFINITY, "at least 1 (1: off)"),
            "cost of a long line's point out in open floor, in caps squared (1: off)",
            screen_open
        ),
        setting!(
            LocalizerConfig,
            "screen_long_line",
            Range::NonNegative,
            "a scan line at least this long counts for screen_open, metres",
            screen_long_line
        ),
        setting!(
            LocalizerConfig,
            "screened",
            Range::Count,
            "hypotheses kept by the screen and costed coarsely",
            screened
        ),
        setting!(
            LocalizerConfig,
            "screened_approximate",
            Range::Count,
            "on a map built from scans, the most hypotheses any search keeps for the coarse cost (0: no cap)",
            screened_approximate
        ),
        setting!(
            LocalizerConfig,
            "refined",
            Range::Count,
            "hypotheses kept by the coarse cost, refined and costed in full (eq. 7)",
            refined
        ),
        setting!(LocalizerConfig, "refine_points", Range::Count, "scan points used by refinement", refine_points),
        setting!(LocalizerConfig, "refine_iterations", Range::Count, "iterations of refinement", refine.iterations),
        setting!(
            LocalizerConfig,
            "polish_points",
            Range::Count,
            "scan points of the polish of close rivals (0: no polish)",
            polish_points
        ),
        setting!(
            LocalizerConfig,
            "polish_margin",
            Range::NonNegative,
            "rivals within this cost per beam of the best are polished",
            polish_margin
        ),
        setting!(LocalizerConfig, "polish_iterations", Range::Count, "iterations of the polish", polish_iterations),
        setting!(
            LocalizerConfig,
            "first_corners",
            Range::Count,
            "scan corners of the cheap first look (0: no first look; never on a map built from scans)",
            first_look.corners
        ),
        setting!(
            LocalizerConfig,
            "first_prescreened",
            Range::Count,
            "first look: candidates kept by the first screening pass",
            first_look.prescreened
        ),
        setting!(
            LocalizerConfig,
            "first_screened",
            Range::Count,
            "first look: hypotheses kept by the screen",
            first_look.screened
        ),
        setting!(LocalizerConfig, "first_refined", Range::Count, "first look: hypotheses refined", first_look.refined),
        setting!(
            LocalizerConfig,
            "first_inliers",
            Range::Fraction,
            "first look: fewest beams agreeing with the map to confirm its pose",
            first_look.min_inliers
        ),
        setting!(
            LocalizerConfig,
            "first_through",
            Range::Fraction,
            "first look: most beams through walls to confirm its pose",
            first_look.max_through
        ),
        setting!(
            LocalizerConfig,
            "first_twin_corners",
            Range::Count,
            "first look: scan corners searched for a twin of a pose it is sure of (0: no twin look)",
            first_look.twins.corners
        ),
        setting!(
            LocalizerConfig,
            "first_twin_bound",
            Range::Positive,
            "twin look: poses the screen rates at most this many times the sure pose are searched",
            first_look.twins.bound
        ),
        setting!(
            LocalizerConfig,
            "first_twin_prescreened",
            Range::Count,
            "twin look: candidates kept by the first screening pass",
            first_look.twins.prescreened
        ),
        setting!(
            LocalizerConfig,
            "first_twin_screened",
            Range::Count,
            "twin look: hypotheses kept by the screen",
            first_look.twins.screened
        ),
        setting!(
            LocalizerConfig,
            "first_twin_refined",
            Range::Count,
            "twin look: hypotheses refined",
            first_look.twins.refined
        ),
        setting!(LocalizerConfig, "coarse_beams", Range::Count, "beams of the coarse cost", coarse_beams),
        setting!(
            LocalizerConfig,
            "coarse_sigma",
            Range::Positive,
            "noise floor of the coarse cost, metres",
            coarse_sigma
        ),
        setting!(
            LocalizerConfig,
            "sparse_beams",
            Range::Count,
            "beams of the sparse cost that thins many screened hypotheses",
            sparse_beams
        ),
        setting!(LocalizerConfig, "sparse_kept", Range::Count, "hypotheses the sparse cost keeps", sparse_kept),
        setting!(LocalizerConfig, "arm_slack", Range::NonNegative, "slack of the arm fit test, metres", arm_slack),
        setting!(
            LocalizerConfig,
            "map_sigma",
            Range::NonNegative,
            "a floor on the map's accuracy, metres",
            cost.sigma_floor
        ),
        setting!(LocalizerConfig, "cost_stride", Range::Step, "eq. 7 reads every this many beams", cost.stride),
        setting!(
            LocalizerConfig,
            "front_cap",
            Range::NonNegative,
            "cap of a residual in front of a wall, squared standard deviations",
            cost.front_cap
        ),
        setting!(
            LocalizerConfig,
            "through_cap",
            Range::NonNegative,
            "cap of a residual behind a wall or a missing return",
            cost.through_cap
        ),
        setting!(
            LocalizerConfig,
            "grazing_cap",
            Range::Within(1.0, f64::INFINITY, "at least 1 (1: off)"),
            "cap of a residual across a wall seen at a grazing angle (1: off)",
            cost.grazing_cap
        ),
        setting!(
            LocalizerConfig,
            "clutter_share",
            Range::Within(0.0, 1.0, "from 0 to 1 (1: off)"),
            "cap of a reading short of the wall by furniture's depth, share of front_cap (1: off)",
            cost.clutter_share
        ),
        setting!(
            LocalizerConfig,
            "edge_step_deg",
            Range::Degrees,
            "beams at most this far apart passing a wall's end are not seen through it (0: off; drawn maps)",
            cost.edge_step
        ),
        setting!(
            LocalizerConfig,
            "clutter_min",
            Range::NonNegative,
            "less than this short of a wall is misalignment, not furniture, metres",
            cost.clutter_min
        ),
        setting!(
            LocalizerConfig,
            "clutter_reach",
            Range::Within(0.0, 1.3, "from 0 to 1.3 metres"),
            "how far from a wall furniture reaches, metres",
            cost.clutter_reach
        ),
        SettingSpec {
            key: "paper_cost",
            range: Range::Switch,
            meaning: "eq. 7 as printed, two-sided (1), or the one-sided cost (0)",
            get: |c| f64::from(u8::from(c.cost.kind == CostKind::Paper)),
            put: |c, v| c.cost.kind = if v != 0.0 { CostKind::Paper } else { CostKind::OneSided },
        },
        setting!(
            LocalizerConfig,
            "surface_dropouts",
            Range::Count,
            "missing returns on surfaces that make a sensor read no return as unknown (0: never)",
            surface_dropouts
        ),
        setting!(
            LocalizerConfig,
            "inside_only",
            Range::Switch,
            "never answer with a pose outside a closed building or the surveyed free space",
            inside_only
        ),
        setting!(
            LocalizerConfig,
            "ambiguity",
            Range::NonNegative,
            "the best pose is ambiguous when a distinct rival costs less than this much more per beam",
            ambiguity_margin
        ),
        setting!(
            LocalizerConfig,
            "ambiguity_ratio",
            Range::NonNegative,
            "...or less than this share of the best's own cost more (after the last search)",
            ambiguity_ratio
        ),
        setting!(
            LocalizerConfig,
            "ambiguity_approximate",
            Range::NonNegative,
            "ambiguity on a map built from scans (its walls known only to their spread)",
            ambiguity_margin_approximate
        ),
        setting!(
            LocalizerConfig,
            "cornerless_tie",
            Range::NonNegative,
            "in a scan with no corner, a pose slid along the wall ties within this cost",
            cornerless_tie
        ),
        setting!(
            LocalizerConfig,
            "min_inliers",
            Range::Fraction,
            "the best pose fails with fewer beams than this agreeing with the map",
            min_inliers
        ),
        setting!(
            LocalizerConfig,
            "max_through",
            Range::Fraction,
            "the best pose fails with more beams than this through walls",
            max_through
        ),
        setting!(
            LocalizerConfig,
            "max_through_approximate",
            Range::Fraction,
            "max_through for maps with a sigma of 5 cm or more",
            max_through_approximate
        ),
        setting!(
            LocalizerConfig,
            "front_cap_approximate",
            Range::NonNegative,
            "front_cap for maps with a sigma of 5 cm or more",
            front_cap_approximate
        ),
        setting!(
            LocalizerConfig,
            "clutter_share_approximate",
            Range::Within(0.0, 1.0, "from 0 to 1 (1: off)"),
            "clutter_share for maps with a sigma of 5 cm or more (1: off)",
            clutter_share_approximate
        ),
        setting!(
            LocalizerConfig,
            "max_through_ok",
            Range::Fraction,
            "a pose with more beams than this through walls is at best ambiguous",
            max_through_ok
        ),
        setting!(
            LocalizerConfig,
            "min_constraint_ok_approximate",
            Range::NonNegative,
            "on a built map, the best pose is ambiguous unless the scan pins it down along every direction by this many points' worth (0: off)",
            min_constraint_ok_approximate
        ),
        setting!(
            LocalizerConfig,
            "ok_probe_position",
            Range::NonNegative,
            "an ok pose must cost ok_probe_margin a beam less than itself moved this far either way along the direction the scan pins down least, or turned 5 degrees either way, metres (0: no probes)",
            ok_probes.position
        ),
        setting!(
            LocalizerConfig,
            "ok_probe_margin",
            Range::NonNegative,
            "how much more a beam each probe of an ok pose must cost by eq. 7",
            ok_probes.margin
        ),
        SettingSpec {
            key: "track",
            range: Range::NonNegative,
            meaning: "search only within this distance of the last pose, metres (0: always global)",
            get: |c| c.track_radius.unwrap_or(0.0),
            put: |c, v| c.track_radius = Some(v).filter(|&r| r > 0.0),
        },
        setting!(
            LocalizerConfig,
            "slide_lines",
            Range::Count,
            "slide: the scan's longest lines laid along map walls",
            slide.lines
        ),
        setting!(
            LocalizerConfig,
            "slide_min_length",
            Range::NonNegative,
            "slide: shortest line used, metres",
            slide.min_length
        ),
        setting!(
            LocalizerConfig,
            "slide_min_wall",
            Range::NonNegative,
            "slide: shortest wall a longer line is laid over, metres",
            slide.min_wall
        ),
        setting!(
            LocalizerConfig,
            "slide_step",
            Range::Positive,
            "slide: distance between positions along a wall, metres",
            slide.step
        ),
        setting!(
            LocalizerConfig,
            "slide_slack",
            Range::NonNegative,
            "slide: how far a line may reach past a wall's ends, metres",
            slide.slack
        ),
        setting!(
            LocalizerConfig,
            "slide_shorter",
            Range::NonNegative,
            "slide: a shorter wall is used when at least this share of the line (above 1: off)",
            slide.shorter_walls
        ),
        setting!(
            LocalizerConfig,
            "slide_screened",
            Range::Count,
            "slide: candidates kept by the screen",
            slide.screened
        ),
        setting!(LocalizerConfig, "slide_max_poses", Range::Count, "slide: most poses made per scan", slide.max_poses),
        setting!(
            LocalizerConfig,
            "slide_sigma_deg",
            Range::Degrees,
            "slide: largest direction uncertainty of a line used",
            slide.max_direction_sigma
        ),
        setting!(
            LocalizerConfig,
            "slide_loose_sigma_deg",
            Range::Degrees,
            "loose slide: largest direction uncertainty (at most slide_sigma_deg: no loose slide)",
            slide.loose_direction_sigma
        ),
        setting!(
            LocalizerConfig,
            "slide_loose_screened",
            Range::Count,
            "loose slide: candidates kept by the screen",
            slide.loose_screened
        ),
        setting!(
            LocalizerConfig,
            "slide_loose_lines",
            Range::Count,
            "loose slide: lines used (0: no loose slide)",
            slide.loose_lines
        ),
        setting!(
            LocalizerConfig,
            "slide_min_inliers_ok",
            Range::Fraction,
            "slide: fewest beams agreeing with the map for an ok pose",
            slide.min_inliers_ok
        ),
        setting!(
            LocalizerConfig,
            "escalate_through",
            Range::Fraction,
            "search wider when the best pose sees through walls with more than this share of beams (1: never)",
            escalate_through
        ),
        setting!(
            LocalizerConfig,
            "escalate_min_beams",
            Range::Count,
            "...and with at least this many beams",
            escalate_min_beams
        ),
        setting!(
            LocalizerConfig,
            "grid_headings",
            Range::Count,
            "grid search: most headings tried (0: no grid search)",
            grid.headings
        ),
        setting!(
            LocalizerConfig,
            "grid_step",
            Range::Positive,
            "grid search: distance between positions, metres",
            grid.step
        ),
        setting!(LocalizerConfig, "grid_max_poses", Range::Count, "grid search: most poses made", grid.max_poses),
        setting!(
            LocalizerConfig,
            "grid_prescreened",
            Range::Count,
            "grid search: candidates kept by the first screening pass",
            grid.prescreened
        ),
        setting!(
            LocalizerConfig,
            "grid_screened",
            Range::Count,
            "grid search: hypotheses kept by the screen",
            grid.screened
        ),
        setting!(
            LocalizerConfig,
            "error_constant",
            Range::Positive,
            "e(d): the sensor's constant error, metres (eqs. 1-2)",
            error.constant
        ),
        setting!(
            LocalizerConfig,
            "error_proportional",
            Range::NonNegative,
            "e(d): the sensor's error per metre of range (0.01 = 1 %)",
            error.proportional
        ),
    ];

    /// Applies `s` when it names a localization parameter: `Ok(true)`; `Ok(false)` when it
    /// names none.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<bool, SettingError> {
        set_by_table(Self::SETTINGS, self, s)
    }
}

/// One alpha of the sequential localizer's odometry motion model, by its index.
macro_rules! odometry_alpha {
    ($key:literal, $k:literal, $meaning:literal) => {
        SettingSpec::<SequentialConfig> {
            key: $key,
            range: Range::NonNegative,
            meaning: $meaning,
            get: |c| c.motion.alphas[$k],
            put: |c, v| c.motion.alphas[$k] = v,
        }
    };
}

impl SequentialConfig {
    /// The sequential localizer's parameters settable by name: the odometry motion model, as
    /// AMCL's `alpha1`-`alpha4` (variances per squared radian or metre of the motion).
    pub const SETTINGS: &'static [SettingSpec<SequentialConfig>] = &[
        odometry_alpha!("odom_alpha1", 0, "odometry: a turn's error from turning (AMCL's alpha1)"),
        odometry_alpha!("odom_alpha2", 1, "odometry: a turn's error from driving (AMCL's alpha2)"),
        odometry_alpha!("odom_alpha3", 2, "odometry: a drive's error from driving (AMCL's alpha3)"),
        odometry_alpha!("odom_alpha4", 3, "odometry: a drive's error from turning (AMCL's alpha4)"),
    ];
}

impl Gema2Config {
    /// The map-corner parameters settable by name (the corners the localizer matches).
    pub const MAP_SETTINGS: &'static [SettingSpec<MapCornerConfig>] = &[
        setting!(
            MapCornerConfig,
            "map_reach",
            Range::NonNegative,
            "how far a map corner's junction may lie beyond a wall's end, metres",
            reach
        ),
        // the scan's own keys: the map makes its corners as the scan does
        setting!(
            MapCornerConfig,
            "reach",
            Range::NonNegative,
            "how far a corner may lie beyond a line's visible end, metres",
            short_reach
        ),
        setting!(
            MapCornerConfig,
            "long_line",
            Range::NonNegative,
            "a line at least this long is long (for long_reach), metres",
            long_wall
        ),
        setting!(
            MapCornerConfig,
            "wall_ends",
            Range::Switch,
            "also match wall ends, ranked with the corners",
            wall_ends
        ),
    ];

    /// What differs between the map-corner settings of this configuration and those a map
    /// model was `built` with, as `key: built vs ours`; `None` when they agree. A localizer
    /// must not match corners against a model built for other settings.
    pub fn model_disagreement(&self, built: &MapCornerConfig) -> Option<String> {
        if *built == self.map_corners {
            return None;
        }
        let named: Vec<String> = Self::MAP_SETTINGS
            .iter()
            .filter(|s| s.shown(built) != s.shown(&self.map_corners))
            .map(|s| format!("{} = {} there, {} here", s.key, s.shown(built), s.shown(&self.map_corners)))
            .collect();
        Some(if named.is_empty() { format!("{built:?} there, {:?} here", self.map_corners) } else { named.join(", ") })
    }

    /// Every key [`set`](Self::set) knows.
    pub fn keys() -> impl Iterator<Item = &'static str> + Clone {
        let segment = SegmenterConfig::SETTINGS.iter().map(|s| s.key);
        let localize = LocalizerConfig::SETTINGS.iter().map(|s| s.key);
        let sequential = SequentialConfig::SETTINGS.iter().map(|s| s.key);
        segment.chain(localize).chain(Self::MAP_SETTINGS.iter().map(|s| s.key)).chain(sequential)
    }

    /// Every key with its value in `self`, its range and meaning, grouped by stage; a key
    /// several configurations take is listed once.
    pub fn rows(&self) -> Vec<SettingRow> {
        let in_localize = |key: &str| {
            LocalizerConfig::SETTINGS.iter().any(|s| s.key == key) || Self::MAP_SETTINGS.iter().any(|s| s.key == key)
        };
        let mut rows: Vec<SettingRow> = SegmenterConfig::SETTINGS
            .iter()
            .map(|s| SettingRow {
                stage: if in_localize(s.key) { "segment, localize" } else { "segment" },
                key: s.key,
                default: s.shown(&self.segmenter),
                range: s.range.describe(),
                meaning: s.meaning,
            })
            .collect();
        let localize = LocalizerConfig::SETTINGS.iter().map(|s| (s.key, s.shown(&self.localizer), s.range, s.meaning));
        let map = Self::MAP_SETTINGS.iter().map(|s| (s.key, s.shown(&self.map_corners), s.range, s.meaning));
        for (key, default, range, meaning) in localize.chain(map) {
            if !rows.iter().any(|r| r.key == key) {
                rows.push(SettingRow { stage: "localize", key, default, range: range.describe(), meaning });
            }
        }
        rows.extend(SequentialConfig::SETTINGS.iter().map(|s| SettingRow {
            stage: SEQUENTIAL,
            key: s.key,
            default: s.shown(&self.sequential),
            range: s.range.describe(),
            meaning: s.meaning,
        }));
        // one group per stage: a shared key between the two stages' own
        rows.sort_by_key(|r| {
            ["segment", "segment, localize", "localize", SEQUENTIAL].iter().position(|&s| s == r.stage)
        });
        rows
    }

    /// Applies `s` to every configuration it concerns: a key shared by segmentation and
    /// localization (the error model, `wall_ends`) is set in both, so the stages agree.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<(), SettingError> {
        let mut known = self.segmenter.set(s)?;
        known |= self.localizer.set(s)?;
        known |= set_by_table(Self::MAP_SETTINGS, &mut self.map_corners, s)?;
        known |= set_by_table(SequentialConfig::SETTINGS, &mut self.sequential, s)?;
        match known {
            true => Ok(()),
            false => Err(SettingError::unknown(s.key, Self::keys())),
        }
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
        // the map makes its corners with the scan's reach and long lines
        c.apply(&["reach=0.7", "long_line=0.9"]).unwrap();
        assert_eq!((c.segmenter.corner.reach, c.map_corners.short_reach), (0.7, 0.7));
        assert_eq!((c.segmenter.corner.long_line, c.map_corners.long_wall), (0.9, 0.9));
    }

    /// The odometry's alphas, named as AMCL names them, set the sequential localizer's motion
    /// model and nothing else; a negative one is refused.
    #[test]
    fn the_odometry_alphas_set_the_sequential_localizer_s_motion_model() {
        let plain = Gema2Config::default();
        let mut c = plain;
        c.apply(&["odom_alpha1=0.2", "odom_alpha2=0.03", "odom_alpha3=0.4", "odom_alpha4=0.05"]).unwrap();
        assert_eq!(c.sequential.motion.alphas, [0.2, 0.03, 0.4, 0.05]);
        assert_eq!(c.sequential, SequentialConfig { motion: c.sequential.motion, ..plain.sequential });
        assert_eq!(format!("{:?}", (c.segmenter, c.localizer)), format!("{:?}", (plain.segmenter, plain.localizer)));
        let err = c.apply(&["odom_alpha1=0.1", "odom_alpha3=-0.1"]).unwrap_err();
        assert!(matches!(err, SettingError::OutOfRange { .. }) && err.to_string().contains("odom_alpha3"), "{err}");
        assert_eq!(c.sequential.motion.alphas, [0.2, 0.03, 0.4, 0.05]);
        let row = plain.rows().into_iter().find(|r| r.key == "odom_alpha2").unwrap();
        assert_eq!((row.stage, row.default.as_str()), (SEQUENTIAL, "0.02"));
    }

    /// The single scan's probes are set by name, and 0 turns them off.
    #[test]
    fn the_ok_probes_are_set_by_name() {
        let mut c = Gema2Config::default();
        c.apply(&["ok_probe_position=0.4", "ok_probe_margin=0.2"]).unwrap();
        assert_eq!((c.localizer.ok_probes.position, c.localizer.ok_probes.margin), (0.4, 0.2));
        c.apply(&["ok_probe_position=0"]).unwrap();
        assert_eq!(c.localizer.ok_probes.position, 0.0);
        assert!(c.apply(&["ok_probe_margin=-1"]).is_err());
    }

    #[test]
    fn unknown_or_malformed_settings_change_nothing() {
        let mut c = Gema2Config::default();
        let before = format!("{c:?}");
        let err = c.apply(&["screened=100", "screend=5"]).unwrap_err();
        assert!(err.to_string().contains("\"screend\" (did you mean \"screened\"?)"), "{err}");
        assert!(err.to_string().contains("gema2 settings"), "{err}");
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

    /// The tables are the only list of keys, so what is listed is what is accepted; checked
    /// both ways all the same, against a value inside every key's range.
    #[test]
    fn every_listed_key_is_accepted_and_every_accepted_key_is_listed() {
        let rows = Gema2Config::default().rows();
        for key in Gema2Config::keys() {
            assert!(rows.iter().any(|r| r.key == key), "{key} is accepted but not listed");
            let mut c = Gema2Config::default();
            assert!(c.apply(&[format!("{key}=1")]).is_ok(), "{key}");
        }
        for r in &rows {
            assert!(Gema2Config::keys().any(|k| k == r.key), "{} is listed but not accepted", r.key);
            assert!(!r.meaning.is_empty() && !r.range.is_empty(), "{} is listed without a meaning", r.key);
        }
        let mut keys: Vec<&str> = rows.iter().map(|r| r.key).collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), rows.len(), "a key listed twice");
    }

    /// A default read back through its key sets the same parameter: the table reads and writes
    /// one field, in the units the user writes (degrees for angles).
    #[test]
    fn every_default_set_by_its_key_changes_nothing() {
        let plain = Gema2Config::default();
        for r in plain.rows() {
            let mut c = Gema2Config::default();
            c.apply(&[format!("{}={}", r.key, r.default)]).unwrap();
            assert_eq!(format!("{c:?}"), format!("{plain:?}"), "{}={}", r.key, r.default);
        }
        let merge = plain.rows().into_iter().find(|r| r.key == "merge_angle").unwrap();
        assert_eq!(merge.default.parse::<f64>().unwrap(), plain.segmenter.filter.merge_angle.to_degrees());
        assert_eq!(merge.stage, "segment");
        let error = plain.rows().into_iter().find(|r| r.key == "error_constant").unwrap();
        assert_eq!(error.stage, "segment, localize");
    }
}
