//! The ROS 2 bridge stage: gema2 on a ROS 2 robot, over DDS, with no ROS installation.
//!
//! - In: `sensor_msgs/LaserScan` (sensor-data QoS) becomes `gema2/scan`, so the rest of the
//!   pipeline is unchanged; `/tf_static` gives the laser's place on the robot; `nav_msgs/Odometry`
//!   on `--odom-topic` goes with each scan, at its stamp ([`odometry`]).
//! - Out: every located scan's pose as `geometry_msgs/PoseWithCovarianceStamped` on
//!   `/gema2/pose`, the robot's (`base_link`, REP 105) in frame `map`, stamped with the scan's
//!   time; with `--initialpose` an `ok` pose also seeds Nav2's AMCL on `/initialpose`,
//!   rate-limited.
//!
//! One job: translate between ROS 2 and the pipeline. Pure parts ([`covariance`], the static frames of `ros::frames`,
//! [`odometry`], [`seeding`]) are libraries with tests; [`node`] is the process. Depends on `ros` (the
//! messages), `messages` (the wire), `acquire` (a scan as a message) and `ros2-client`.

pub mod covariance;
pub mod node;
pub mod odometry;
pub mod seeding;
