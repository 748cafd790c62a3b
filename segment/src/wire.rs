//! Conversions between this crate's types and the wire types of `messages`. Everything read
//! from shared memory is checked before the algorithms see it.

use crate::corner::{Arm, Corner};
use crate::line::Line;
use laser::{ScanGeometry, ScanView};
use messages::{ArmMsg, CornerMsg, LineMsg, ScanMsg, MAX_BEAMS};
use nalgebra::{Point2, Vector2};

/// A scan message as a view, if its layout and count are usable.
pub fn scan_view(msg: &ScanMsg) -> Result<ScanView<'_>, String> {
    let geometry = ScanGeometry {
        angle_min: msg.angle_min,
        angle_increment: msg.angle_increment,
        range_min: msg.range_min,
        range_max: msg.range_max,
    };
    if !geometry.is_well_formed() {
        return Err(format!("scan {}: unusable layout {geometry:?}", msg.header.seq));
    }
    let count = msg.count as usize;
    if count > MAX_BEAMS {
        return Err(format!("scan {}: {count} readings, at most {MAX_BEAMS}", msg.header.seq));
    }
    Ok(ScanView { geometry, ranges: &msg.ranges[..count] })
}

pub fn line_to_msg(l: &Line) -> LineMsg {
    LineMsg {
        start: [l.start.x, l.start.y],
        end: [l.end.x, l.end.y],
        direction_sigma: l.direction_sigma,
        samples: l.samples,
        _pad: 0,
    }
}

fn arm_to_msg(a: &Arm) -> ArmMsg {
    ArmMsg {
        direction: [a.direction.x, a.direction.y],
        gap: a.gap,
        length: a.length,
        samples: a.samples,
        direction_sigma: a.direction_sigma,
        line: a.line as u32,
        _pad: 0,
    }
}

fn arm_from_msg(a: &ArmMsg) -> Arm {
    Arm {
        direction: Vector2::new(a.direction[0], a.direction[1]),
        gap: a.gap,
        length: a.length,
        samples: a.samples,
        direction_sigma: a.direction_sigma,
        line: a.line.min(u16::MAX as u32) as u16,
    }
}

pub fn corner_to_msg(c: &Corner) -> CornerMsg {
    CornerMsg {
        position: [c.position.x, c.position.y],
        inner_angle: c.inner_angle,
        orientation: c.orientation,
        quality: c.quality,
        arms: [arm_to_msg(&c.arms[0]), arm_to_msg(&c.arms[1])],
    }
}

/// A corner from the wire; `None` if any number is not finite.
pub fn corner_from_msg(m: &CornerMsg) -> Option<Corner> {
    let c = Corner {
        position: Point2::new(m.position[0], m.position[1]),
        inner_angle: m.inner_angle,
        orientation: m.orientation,
        quality: m.quality,
        arms: [arm_from_msg(&m.arms[0]), arm_from_msg(&m.arms[1])],
    };
    let arms =
        c.arms.iter().flat_map(|a| [a.direction.x, a.direction.y, a.gap, a.length, a.samples, a.direction_sigma]);
    let finite = [c.position.x, c.position.y, c.inner_angle, c.orientation, c.quality]
        .into_iter()
        .chain(arms)
        .all(f64::is_finite);
    finite.then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_cross_the_wire_unchanged_and_bad_ones_are_refused() {
        let arm = |x: f64| Arm {
            direction: Vector2::new(x, 1.0 - x),
            gap: 0.1,
            length: 2.0,
            samples: 40.0,
            direction_sigma: 0.01,
            line: 3,
        };
        let c = Corner {
            position: Point2::new(1.5, -2.0),
            inner_angle: 1.6,
            orientation: 0.3,
            quality: 1.2,
            arms: [arm(0.6), arm(0.8)],
        };
        assert_eq!(corner_from_msg(&corner_to_msg(&c)), Some(c));
        let mut bad = corner_to_msg(&c);
        bad.arms[1].gap = f64::NAN;
        assert_eq!(corner_from_msg(&bad), None);
    }
}
