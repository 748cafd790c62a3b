//! GEMA2 localization (paper section 5): scan corners matched against the map's corners give
//! pose hypotheses (eqs. 5-6), which the ray-cast cost function (eq. 7) ranks.
//!
//! One job: localization, as a library ([`Localizer`], [`Gema2`] for segmentation and
//! localization together) and as the pipeline's localize stage (`node`, with the default
//! feature `process`). The searches it runs are one list, [`CASCADE`]. Depends on `laser`,
//! `segment` and `map`; with `process`, on `messages` (the map model comes from the map server) and
//! `clap` for the stage. Without it, no iceoryx2, clap or libc.

pub mod cost;
pub mod gema2;
pub mod grid;
pub mod localizer;
mod lowest;
pub mod matching;
#[cfg(feature = "process")]
pub mod node;
pub mod refine;
pub mod sequential;
pub mod settings;
pub mod slide;

pub use cost::{Cost, CostConfig, CostKind};
pub use gema2::{Gema2, Gema2Config};
pub use grid::{GridConfig, FROM_GRID};
pub use localizer::{
    same_pose, FirstLook, Hypothesis, Judgement, Localization, Localizer, LocalizerConfig, LocateTimes, Probes, Ran,
    Status, Step, TwinLook, CASCADE,
};
pub use map::model::{self, MapModel};
pub use matching::pose_from_corners;

/// The localize stage's implementations, what `gema2 swap` takes for one: a swap to the same
/// name starts a fresh process (a new build, once installed) beside the running one.
/// `sequential` is [`Sequential`]: hypotheses carried from scan to scan by the odometry the
/// scans carry.
pub const LOCALIZERS: [&str; 2] = ["gema2", "sequential"];
pub use refine::RefineConfig;
pub use sequential::{Sequential, SequentialAnswer, SequentialConfig};
pub use slide::{SlideConfig, FROM_SLIDE};
