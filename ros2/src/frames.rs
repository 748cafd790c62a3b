//! The laser's place on the robot, from `/tf_static`: the chain of static transforms from the
//! robot's frame (`base_link`) down to the scan's `frame_id`, composed in the plane.

use laser::{pose, Pose};
use std::collections::HashMap;

/// Static transforms by child frame: its parent and its pose in the parent's frame.
#[derive(Clone, Debug, Default)]
pub struct StaticFrames {
    parents: HashMap<String, (String, Pose)>,
}

/// A frame name without the leading `/` some publishers still write.
fn frame(name: &str) -> &str {
    name.trim_start_matches('/')
}

/// Longest chain followed: more is a loop.
const DEEPEST: usize = 64;

impl StaticFrames {
    /// Adds (or replaces) `child`'s pose `x, y, yaw` in `parent`'s frame.
    pub fn insert(&mut self, parent: &str, child: &str, x: f64, y: f64, yaw: f64) {
        if [x, y, yaw].iter().all(|v| v.is_finite()) && frame(parent) != frame(child) {
            self.parents.insert(frame(child).to_owned(), (frame(parent).to_owned(), pose(x, y, yaw)));
        }
    }

    /// The pose of `child` in `base`'s frame, when the transforms reach from one to the other.
    pub fn pose_of(&self, child: &str, base: &str) -> Option<Pose> {
        let (child, base) = (frame(child), frame(base));
        let mut at = child;
        let mut p = Pose::identity();
        for _ in 0..DEEPEST {
            if at == base {
                return Some(p);
            }
            let (parent, t) = self.parents.get(at)?;
            p = t * p;
            at = parent;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose_theta;

    #[test]
    fn a_chain_of_static_transforms_composes() {
        let mut f = StaticFrames::default();
        f.insert("base_link", "/laser_mount", 0.2, 0.0, std::f64::consts::FRAC_PI_2);
        f.insert("laser_mount", "laser", 0.1, 0.0, 0.0);
        let p = f.pose_of("laser", "/base_link").unwrap();
        assert!((p.translation.x - 0.2).abs() < 1e-12 && (p.translation.y - 0.1).abs() < 1e-12);
        assert!((pose_theta(&p) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(f.pose_of("base_link", "base_link"), Some(Pose::identity()));
        assert_eq!(f.pose_of("camera", "base_link"), None);
    }

    #[test]
    fn a_loop_or_a_bad_transform_is_no_answer() {
        let mut f = StaticFrames::default();
        f.insert("a", "b", 1.0, 0.0, 0.0);
        f.insert("b", "a", 1.0, 0.0, 0.0);
        assert_eq!(f.pose_of("a", "base_link"), None);
        f.insert("base_link", "laser", f64::NAN, 0.0, 0.0);
        assert_eq!(f.pose_of("laser", "base_link"), None);
    }
}
