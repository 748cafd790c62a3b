//! The search cascade: which searches a scan runs, in which order, and when each runs.
//!
//! Every step makes candidate poses from its source, keeps the best by the distance-field
//! screen and the coarse eq. 7, refines them and ranks them by the full eq. 7 together with
//! every earlier step's (see the parent module). The steps differ in where their poses come
//! from, how many they keep, and when they run:
//!
//! | step | runs when | poses from | kept by screen / coarse cost |
//! |---|---|---|---|
//! | [`Step::FirstLook`] | always (the paper's search), but on a map built from scans | the best scan corner | `first_look` budgets |
//! | [`Step::FullSearch`] | no pose is confirmed | the `corners_tried` best corners | `screened` / `refined` |
//! | [`Step::Slide`] | no pose is confirmed | the longest sure lines along every wall | `slide.screened` / `refined` |
//! | [`Step::LooseSlide`] | after the slide, the answer is not `ok` | lines of uncertain direction | `slide.loose_screened` / `refined` |
//! | [`Step::WiderSlide`] | after the slide, the best pose sees through walls | the slide's, wider | [`LocalizerConfig::escalated`] |
//! | [`Step::Grid`] | after the wider slide, it still sees through walls | a grid over the free space | `grid` budgets, escalated refinement |
//!
//! The first look settles a scan when its best pose fits it closely: on a drawn map a twin
//! elsewhere almost always sees through a wall, so that is enough. On a map built from scans
//! (`WallMap::is_approximate`) it is not: a twin fits as closely, and the first look, having
//! matched one scan corner, never meets the truth to rival it. On the seven CARMEN logs it
//! settled 2-6 % of scans, and 15 of the 29 wrong `ok` answers were among them; run
//! without it, they gave 17 more successes and the same time.
//!
//! The loose slide asks less than "confirmed": an answer the slide made `ok` is kept without
//! it. On a map built from scans a right pose is seldom confirmed (it sees through the map's
//! imperfect walls), so the loose slide ran on 60-90 % of the CARMEN logs' scans; after an
//! `ok` answer it seldom changed one for the better. Run only on answers that are not `ok`,
//! those logs are 15-28 % faster a scan for one wrong `ok` more in 18 142 scans (a turn 6.5
//! degrees off the log's, where every answer nearby is 5-7 degrees off it) and 6 successes
//! more; the simulated suite gives as many successes and wrong `ok`, and the sequential
//! localizer's figures are unchanged.
//!
//! "Confirmed" is [`FirstLook::confirms`](super::FirstLook); "sees through walls" is
//! [`Localizer::escalates`](super::Localizer), the one place that decides escalation. A step
//! switched off by its settings (`first_corners=0`, `slide_lines=0`, `grid_headings=0`,
//! `escalate_through=1`) is passed over, and so are the steps that need it to have run.
//! `docs/how-it-works.md` says what each step costs and buys.

use super::LocalizerConfig;

/// One search of the cascade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The paper's search: the single best scan corner, few hypotheses.
    FirstLook,
    /// The `corners_tried` best scan corners.
    FullSearch,
    /// The scan's longest well-determined lines laid along every map wall ([`crate::slide`]).
    Slide,
    /// The lines the slide passed over for their uncertain direction
    /// ([`crate::slide::loose_slide_lines`]).
    LooseSlide,
    /// The slide once more, with the budgets of [`LocalizerConfig::escalated`].
    WiderSlide,
    /// Poses on a grid over the free space at the headings the scan's lines vote for
    /// ([`crate::grid`]).
    Grid,
}

/// When a step runs, judged on the answer of the steps before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    /// No step so far has confirmed its best pose.
    Unconfirmed,
    /// After the slide search, the answer so far is not `ok` (as the checks after the cascade
    /// would leave it): looser than [`When::Unconfirmed`], which a right pose on a map built
    /// from scans seldom is.
    NotOkAfterSlide,
    /// The best pose so far sees through walls, or there is none.
    SeesThroughWalls,
}

/// A step, the step that must have run before it, and when it runs.
#[derive(Clone, Copy, Debug)]
pub struct StepSpec {
    pub step: Step,
    pub after: Option<Step>,
    pub when: When,
}

/// The cascade, in the order its steps run.
pub const CASCADE: [StepSpec; Step::COUNT] = [
    StepSpec { step: Step::FirstLook, after: None, when: When::Unconfirmed },
    StepSpec { step: Step::FullSearch, after: None, when: When::Unconfirmed },
    StepSpec { step: Step::Slide, after: None, when: When::Unconfirmed },
    StepSpec { step: Step::LooseSlide, after: Some(Step::Slide), when: When::NotOkAfterSlide },
    StepSpec { step: Step::WiderSlide, after: Some(Step::Slide), when: When::SeesThroughWalls },
    StepSpec { step: Step::Grid, after: Some(Step::WiderSlide), when: When::SeesThroughWalls },
];

impl Step {
    pub const COUNT: usize = 6;

    /// Its place in [`CASCADE`] (and in per-step tables).
    pub fn index(self) -> usize {
        self as usize
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Step::FirstLook => "first look",
            Step::FullSearch => "full search",
            Step::Slide => "slide",
            Step::LooseSlide => "loose slide",
            Step::WiderSlide => "wider slide",
            Step::Grid => "grid",
        }
    }

    /// Whether the settings switch the step on. The loose slide also needs lines of its own,
    /// which only the search can tell.
    pub fn switched_on(self, cfg: &LocalizerConfig) -> bool {
        match self {
            Step::FirstLook => cfg.first_look.corners > 0 && cfg.first_look.corners < cfg.corners_tried,
            Step::FullSearch | Step::LooseSlide => true,
            Step::Slide => cfg.slide.lines > 0,
            Step::WiderSlide => cfg.escalate_through < 1.0,
            Step::Grid => cfg.grid.headings > 0,
        }
    }
}

/// The steps one scan ran.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ran(u8);

impl Ran {
    pub fn insert(&mut self, step: Step) {
        self.0 |= 1 << step.index();
    }

    pub fn contains(self, step: Step) -> bool {
        self.0 & (1 << step.index()) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cascade lists every step once, in its index's place, and a step runs only after
    /// steps listed before it.
    #[test]
    fn the_cascade_lists_each_step_once_after_what_it_needs() {
        for (k, spec) in CASCADE.iter().enumerate() {
            assert_eq!(spec.step.index(), k, "{:?}", spec.step);
            if let Some(before) = spec.after {
                assert!(before.index() < k, "{:?} after {before:?}", spec.step);
            }
        }
        let mut ran = Ran::default();
        ran.insert(Step::Slide);
        assert!(ran.contains(Step::Slide) && !ran.contains(Step::Grid));
    }

    /// Each step's switch is the setting the README names for it.
    #[test]
    fn each_step_has_its_switch() {
        let on = LocalizerConfig::default();
        assert!(CASCADE.iter().all(|s| s.step.switched_on(&on)));
        let mut off = on;
        off.first_look.corners = 0;
        off.slide.lines = 0;
        off.grid.headings = 0;
        off.escalate_through = 1.0;
        let still: Vec<Step> = CASCADE.iter().map(|s| s.step).filter(|s| s.switched_on(&off)).collect();
        assert_eq!(still, [Step::FullSearch, Step::LooseSlide]);
    }
}
