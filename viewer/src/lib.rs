//! The gema2 recorder: every pipeline message into a rerun recording (`.rrd` file, live viewer
//! or both), and `inspect`, which reads a recording back with rerun's own decoder.
//!
//! The layout of a recording (entity paths, timelines) is in [`entities`]; rerun is a dependency
//! of this crate only.
//!
//! One job: recordings. Depends on `messages`, `laser`, `map` and `mapserver` (to draw the map
//! from its message), and rerun.

pub mod entities;
pub mod inspect;
pub mod live;
pub mod node;
pub mod output;
pub mod record;

pub use inspect::Inspection;
pub use output::{Output, OutputSpec};
pub use record::{Counts, Recorder};
