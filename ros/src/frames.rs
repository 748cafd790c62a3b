//! The laser's place on the robot, from `/tf_static` (live or in a bag): the chain of static transforms from the
//! robot's frame (`base_link`) down to the scan's `frame_id`, composed in 3D and seen in the
//! plane ([`Mount`]). A laser mounted upside down (its z axis pointing down, a roll of 180
//! degrees) sweeps clockwise as the robot sees it: its mount says so, and its scans are read
//! mirrored, as Nav2's AMCL reads them.

use crate::msg;
use laser::{pose, Pose};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use std::collections::HashMap;

/// Static transforms by child frame: its parent and its pose in the parent's frame.
#[derive(Clone, Debug, Default)]
pub struct StaticFrames {
    parents: HashMap<String, (String, Isometry3<f64>)>,
}

/// A laser's place on the robot as the plane sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mount {
    /// Its position and the heading of its x axis in the robot's frame.
    pub pose: Pose,
    /// Its z axis points down: its beams turn clockwise in the robot's frame, and its scans
    /// are to be read mirrored (`ros::scan::mirrored`).
    pub upside_down: bool,
    /// Degrees between its scan plane and the robot's floor (0 level, upside down too).
    pub tilt_deg: f64,
}

/// A frame name without the leading `/` some publishers still write.
pub fn frame_name(name: &str) -> &str {
    name.trim_start_matches('/')
}

/// Longest chain followed: more is a loop.
const DEEPEST: usize = 64;

/// A transform's `translation` and `rotation` quaternion (x, y, z, w; normalised here) as an
/// isometry. `None` for a transform that is not finite or has no rotation (a zero quaternion).
fn isometry(translation: [f64; 3], rotation: [f64; 4]) -> Option<Isometry3<f64>> {
    let [qx, qy, qz, qw] = rotation;
    let q = Quaternion::new(qw, qx, qy, qz);
    let finite = translation.iter().chain(&rotation).all(|v| v.is_finite());
    (finite && q.norm() >= 1e-9)
        .then(|| Isometry3::from_parts(Translation3::from(translation), UnitQuaternion::from_quaternion(q)))
}

/// `p` as the plane sees it: its translation's x and y, and the heading of its x axis.
fn seen_in_the_plane(p: &Isometry3<f64>) -> Pose {
    let x = p.rotation * Vector3::x();
    pose(p.translation.x, p.translation.y, x.y.atan2(x.x))
}

/// A transform's pose as the plane sees it, as [`StaticFrames::mount_of`] reads a chain.
/// `None` for a transform that is not finite or has no rotation (a zero quaternion); the
/// quaternion need not be normalised.
pub fn planar(t: &msg::Transform) -> Option<Pose> {
    isometry(t.translation, t.rotation).map(|p| seen_in_the_plane(&p))
}

impl StaticFrames {
    /// Adds (or replaces) `child`'s pose in `parent`'s frame: its `translation` and its
    /// `rotation` quaternion (x, y, z, w; normalised here). A transform that is not finite or
    /// has no rotation (a zero quaternion) is left out.
    pub fn insert(&mut self, parent: &str, child: &str, translation: [f64; 3], rotation: [f64; 4]) {
        let Some(t) = isometry(translation, rotation).filter(|_| frame_name(parent) != frame_name(child)) else {
            return;
        };
        self.parents.insert(frame_name(child).to_owned(), (frame_name(parent).to_owned(), t));
    }

    /// Adds (or replaces) every transform of a `/tf_static` message.
    pub fn add(&mut self, tf: &msg::TfMessage) {
        for t in &tf.transforms {
            self.insert(&t.header.frame_id, &t.child_frame_id, t.transform.translation, t.transform.rotation);
        }
    }

    /// Whether no transform is known.
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// Whether `child`'s place is known.
    pub fn places(&self, child: &str) -> bool {
        self.parents.contains_key(frame_name(child))
    }

    /// Where `child` is on `base`, when the transforms reach from one to the other.
    pub fn mount_of(&self, child: &str, base: &str) -> Option<Mount> {
        let (child, base) = (frame_name(child), frame_name(base));
        let mut at = child;
        let mut p = Isometry3::identity();
        for _ in 0..DEEPEST {
            if at == base {
                let z = p.rotation * Vector3::z();
                return Some(Mount {
                    pose: seen_in_the_plane(&p),
                    upside_down: z.z < 0.0,
                    tilt_deg: z.z.abs().clamp(0.0, 1.0).acos().to_degrees(),
                });
            }
            let (parent, t) = self.parents.get(at)?;
            p = t * p;
            at = parent;
        }
        None
    }

    /// The planar pose of `child` in `base`'s frame ([`StaticFrames::mount_of`]).
    pub fn pose_of(&self, child: &str, base: &str) -> Option<Pose> {
        self.mount_of(child, base).map(|m| m.pose)
    }
}

/// The transforms of `/tf` that never changed over a bag: a ROS 1 robot's mounts, which
/// ROS 1's `static_transform_publisher` and older drivers publish there again and again
/// instead of on `/tf_static`. A frame whose transform moved (a joint, odometry) or whose parent
/// changed is not one of them.
#[derive(Clone, Debug, Default)]
pub struct UnchangingTf {
    /// By child: its parent, its first transform, and whether every later one was the same.
    seen: HashMap<String, (String, msg::Transform, bool)>,
}

/// How far two transforms of one mount may differ (metres, and quaternion components) for
/// rounding.
const SAME_TRANSFORM: f64 = 1e-6;

impl UnchangingTf {
    /// Notes every transform of a `/tf` message.
    pub fn observe(&mut self, tf: &msg::TfMessage) {
        for t in &tf.transforms {
            let (parent, child) = (frame_name(&t.header.frame_id), frame_name(&t.child_frame_id));
            match self.seen.get_mut(child) {
                None => {
                    self.seen.insert(child.to_owned(), (parent.to_owned(), t.transform, true));
                }
                Some((p, first, same)) => {
                    let near = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= SAME_TRANSFORM);
                    *same &= p == parent
                        && near(&first.translation, &t.transform.translation)
                        && near(&first.rotation, &t.transform.rotation);
                }
            }
        }
    }

    /// Adds to `frames` the unchanging transforms of the frames it does not place yet:
    /// `/tf_static` has the last word.
    pub fn add_to(&self, frames: &mut StaticFrames) {
        for (child, (parent, t, same)) in &self.seen {
            if *same && !frames.places(child) {
                frames.insert(parent, child, t.translation, t.rotation);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose_theta;
    use std::f64::consts::{FRAC_PI_2, PI};

    impl StaticFrames {
        /// Adds `child`'s planar pose `x, y, yaw` in `parent`'s frame.
        fn insert_planar(&mut self, parent: &str, child: &str, x: f64, y: f64, yaw: f64) {
            let (s, c) = (yaw / 2.0).sin_cos();
            self.insert(parent, child, [x, y, 0.0], [0.0, 0.0, s, c]);
        }
    }

    /// The quaternion (x, y, z, w) of roll, pitch and yaw.
    fn rpy(roll: f64, pitch: f64, yaw: f64) -> [f64; 4] {
        let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        [q.i, q.j, q.k, q.w]
    }

    #[test]
    fn a_chain_of_static_transforms_composes() {
        let mut f = StaticFrames::default();
        f.insert_planar("base_link", "/laser_mount", 0.2, 0.0, FRAC_PI_2);
        f.insert_planar("laser_mount", "laser", 0.1, 0.0, 0.0);
        let p = f.pose_of("laser", "/base_link").unwrap();
        assert!((p.translation.x - 0.2).abs() < 1e-12 && (p.translation.y - 0.1).abs() < 1e-12);
        assert!((pose_theta(&p) - FRAC_PI_2).abs() < 1e-12);
        assert!(!f.mount_of("laser", "base_link").unwrap().upside_down);
        assert_eq!(f.pose_of("base_link", "base_link"), Some(Pose::identity()));
        assert_eq!(f.pose_of("camera", "base_link"), None);
    }

    #[test]
    fn a_laser_mounted_upside_down_is_told_and_keeps_the_heading_of_its_x_axis() {
        let mut f = StaticFrames::default();
        // rolled 180 degrees, facing 30 degrees left, 0.3 m up on a plate 0.1 m forward
        f.insert_planar("base_link", "plate", 0.1, 0.0, 0.0);
        f.insert("plate", "laser", [0.0, 0.05, 0.3], rpy(PI, 0.0, 30f64.to_radians()));
        let m = f.mount_of("laser", "base_link").unwrap();
        assert!(m.upside_down && m.tilt_deg < 1e-6);
        assert!((m.pose.translation.x - 0.1).abs() < 1e-12 && (m.pose.translation.y - 0.05).abs() < 1e-12);
        assert!((pose_theta(&m.pose) - 30f64.to_radians()).abs() < 1e-9, "{}", pose_theta(&m.pose));
        // a beam 10 degrees left of the flipped laser's x axis points 10 degrees right of it
        let laser = f.parents["laser"].1.rotation;
        let beam = laser * Vector3::new(10f64.to_radians().cos(), 10f64.to_radians().sin(), 0.0);
        assert!((beam.y.atan2(beam.x) - 20f64.to_radians()).abs() < 1e-9);
        // flipped twice is upright; pitched 180 degrees is upside down too
        f.insert("laser", "again", [0.0; 3], rpy(PI, 0.0, 0.0));
        assert!(!f.mount_of("again", "base_link").unwrap().upside_down);
        f.insert("base_link", "pitched", [0.0; 3], rpy(0.0, PI, 0.0));
        let m = f.mount_of("pitched", "base_link").unwrap();
        assert!(m.upside_down && (pose_theta(&m.pose).abs() - PI).abs() < 1e-9);
        // a tilt is measured
        f.insert("base_link", "tilted", [0.0; 3], rpy(0.0, 12f64.to_radians(), 0.0));
        assert!((f.mount_of("tilted", "base_link").unwrap().tilt_deg - 12.0).abs() < 1e-9);
    }

    #[test]
    fn a_transform_is_seen_in_the_plane_whatever_its_quaternion_s_scale() {
        let t = |rotation: [f64; 4]| msg::Transform { translation: [1.0, -2.0, 0.4], rotation };
        let [x, y, z, w] = rpy(0.0, 0.0, 2.5);
        for scale in [1.0, 0.01, 7.0] {
            let p = planar(&t([x * scale, y * scale, z * scale, w * scale])).unwrap();
            assert_eq!((p.translation.x, p.translation.y), (1.0, -2.0));
            assert!((pose_theta(&p) - 2.5).abs() < 1e-12, "{scale}: {}", pose_theta(&p));
        }
        // a wheel on an uneven floor: rolled a little, its heading still its x axis's
        let p = planar(&t(rpy(0.05, -0.03, -1.0))).unwrap();
        assert!((pose_theta(&p) + 1.0).abs() < 2e-3, "{}", pose_theta(&p));
        assert_eq!(planar(&t([0.0; 4])), None);
        assert_eq!(planar(&t([0.0, 0.0, f64::NAN, 1.0])), None);
        assert_eq!(
            planar(&msg::Transform { translation: [f64::INFINITY, 0.0, 0.0], rotation: [0.0, 0.0, 0.0, 1.0] }),
            None
        );
    }

    #[test]
    fn a_mount_repeated_on_tf_places_the_laser_and_a_moving_frame_does_not() {
        let t = |parent: &str, child: &str, x: f64| msg::TfMessage {
            transforms: vec![msg::TransformStamped {
                header: msg::Header { stamp: msg::Time::from_nanos(0), frame_id: parent.into() },
                child_frame_id: child.into(),
                transform: msg::Transform { translation: [x, 0.0, 0.0], rotation: [0.0, 0.0, 0.0, 1.0] },
            }],
        };
        let mut tf = UnchangingTf::default();
        for k in 0..5 {
            tf.observe(&t("/base_link", "laser", 0.25));
            tf.observe(&t("odom", "base_link", k as f64));
            tf.observe(&t(if k < 3 { "base_link" } else { "arm" }, "camera", 0.1));
        }
        tf.observe(&t("base_link", "sonar", 0.05));
        let mut frames = StaticFrames::default();
        frames.insert_planar("base_link", "sonar", 0.07, 0.0, 0.0);
        tf.add_to(&mut frames);
        assert_eq!(frames.pose_of("laser", "base_link").map(|p| p.translation.x), Some(0.25));
        // odometry moved, the camera changed parents: neither is a mount
        assert!(!frames.places("base_link") && !frames.places("camera"));
        // /tf_static's own place stands
        assert_eq!(frames.pose_of("sonar", "base_link").map(|p| p.translation.x), Some(0.07));
    }

    #[test]
    fn a_loop_or_a_bad_transform_is_no_answer() {
        let mut f = StaticFrames::default();
        f.insert_planar("a", "b", 1.0, 0.0, 0.0);
        f.insert_planar("b", "a", 1.0, 0.0, 0.0);
        assert_eq!(f.pose_of("a", "base_link"), None);
        f.insert_planar("base_link", "laser", f64::NAN, 0.0, 0.0);
        assert_eq!(f.pose_of("laser", "base_link"), None);
        f.insert("base_link", "laser", [0.0; 3], [0.0; 4]);
        assert_eq!(f.pose_of("laser", "base_link"), None);
    }
}
