//! GEMA2 laser sources: CARMEN log replay and a laser simulator (the Hokuyo SCIP 2.0 driver
//! comes in its own module).
//!
//! One job: laser scans in, as a library and as the pipeline's acquire stage ([`node`]). Depends
//! on `laser`, `map` and `mapio` (the simulator's world), and on `messages` for the stage.

pub mod carmen;
pub mod node;
pub mod scip;
pub mod sim;
pub mod urg_log;

pub use carmen::{
    write_robotlaser1, write_robotlaser1_with_odometry, CarmenReader, FlaserArgs, FlaserError, FlaserLayout, LogError,
    LogScan, NO_TRUTH_MARKER,
};
pub use sim::{Obstacles, Scenario, SensorModel, Simulator, Walk};
