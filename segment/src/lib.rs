//! GEMA2 segmentation (paper section 4): a scan becomes samples with error bounds (eqs. 1-2),
//! lines inferred with the *line visibility* estimator (eq. 3, Codes 1-2), filtered lines
//! (section 4.3) and corners ranked by quality (eq. 4).
//!
//! Internally the paper's (u, v) sensor frame is replaced by the REP 103 sensor frame (x
//! forward, y left): the geometry is the same up to a rotation, and everything this crate
//! returns is in the frame the rest of the project uses.
//!
//! One job: segmentation, as a library ([`segmenter`]) and as the pipeline's segment stage
//! (`node`, with the default feature `process`). Depends on `laser`; with `process`, on
//! `messages` and `clap` for the stage. `cargo build -p segment --no-default-features` builds
//! the algorithm alone, without iceoryx2, clap or libc.

pub mod corner;
pub mod end;
pub mod filter;
/// The total least squares line fit (section 4.2), shared with the tracing of grid maps.
pub use laser::fit;
pub mod inference;
pub mod line;
#[cfg(feature = "process")]
pub mod node;
pub mod noise;
pub mod sample;
pub mod segmenter;
pub mod settings;
pub mod split_merge;
pub mod visibility;
#[cfg(feature = "process")]
pub mod wire;

pub use corner::{Arm, Corner, CornerConfig, CornerRanking};
pub use end::EndConfig;
pub use filter::FilterConfig;
pub use line::Line;
pub use sample::{ErrorModel, Sample};
pub use segmenter::{LineVisibilitySegmenter, SegmentTimes, Segmentation, Segmenter, SegmenterConfig};
pub use settings::{Setting, SettingError};
pub use split_merge::{segmenter_by_name, SplitAndMergeSegmenter, SEGMENTERS};
pub use visibility::LineVisibility;
