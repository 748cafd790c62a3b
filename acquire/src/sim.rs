//! A laser simulator: a wall map plus obstacles the map does not know (people, furniture), seen
//! by a sensor model with range noise, dropouts and mixed pixels at depth jumps.
//!
//! Poses are drawn uniformly over the building's main free space: at least `clearance` from
//! every wall, enclosed (rays in most directions meet a wall), so the robot is never outside,
//! and in the connected region of the free space that holds most of it (see [`FreeSpace`]), so
//! the robot is never inside a rack, a pillar or any other closed outline.
//!
//! A scan from a random pose places its own obstacles about it. A walk ([`Walk`]) keeps its
//! furniture where it was put: boxes stay for the rest of the walk, new ones are put against
//! the walls ahead as the robot comes to them, and the walk goes around them. People are
//! placed afresh each scan: they move.

use laser::motion::{DriftingOdometry, OdometryNoise};
use laser::rng::Rng;
use laser::{pose, LaserScan, Pose, ScanGeometry};
use map::{DistanceField, FreeSpace, RayCaster, RayScratch, Wall, WallMap};
use nalgebra::{Point2, Vector2};
use std::f64::consts::TAU;
use std::str::FromStr;

/// Which obstacles the map lacks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scenario {
    /// Walls only.
    Clean,
    /// 1-4 people (cylinders of 0.2-0.4 m) within 0.6-3 m of the robot, in view.
    People,
    /// 2-5 boxes (0.4-1.6 x 0.3-0.8 m) against walls the robot sees; on a walk, boxes that
    /// stay where they were put, four within reach of the robot.
    Furniture,
}

impl FromStr for Scenario {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "clean" => Ok(Scenario::Clean),
            "people" => Ok(Scenario::People),
            "furniture" => Ok(Scenario::Furniture),
            _ => Err(format!("unknown scenario {s:?}: clean, people or furniture")),
        }
    }
}

impl std::fmt::Display for Scenario {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Scenario::Clean => "clean",
            Scenario::People => "people",
            Scenario::Furniture => "furniture",
        })
    }
}

/// How the simulated sensor errs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorModel {
    pub geometry: ScanGeometry,
    pub beams: usize,
    /// Range noise standard deviation: `noise_constant + noise_proportional * range`.
    pub noise_constant: f64,
    pub noise_proportional: f64,
    /// Probability that a reading is lost: reported as 0 (an error code, as the URG-04LX
    /// does), or as the maximum range when `dropout_reads_max`.
    pub dropout: f64,
    /// Lost readings read as the maximum range, as a SICK LMS reports them (81.91 m in the
    /// CARMEN logs), indistinguishable from a beam that met nothing in range.
    pub dropout_reads_max: bool,
    /// Probability that a beam at a depth jump returns a mix of both surfaces.
    pub mixed_pixel: f64,
    /// Depth difference between neighbouring beams that counts as a jump, metres.
    pub jump: f64,
}

impl SensorModel {
    /// A Hokuyo URG-04LX: 682 beams over 240 degrees, 0.02-5.6 m, 1 cm + 0.5 % noise.
    pub fn urg04lx() -> Self {
        SensorModel {
            geometry: ScanGeometry::urg04lx(),
            beams: ScanGeometry::urg04lx_beams(1),
            noise_constant: 0.01,
            noise_proportional: 0.005,
            dropout: 0.005,
            dropout_reads_max: false,
            mixed_pixel: 0.5,
            jump: 0.15,
        }
    }

    /// The URG-04LX field of view sampled with `beams` beams.
    pub fn urg04lx_with_beams(beams: usize) -> Self {
        let mut m = Self::urg04lx();
        let fov = m.geometry.angle_increment * (m.beams - 1) as f64;
        m.geometry.angle_increment = fov / (beams.max(2) - 1) as f64;
        m.beams = beams.max(2);
        m
    }
}

/// Obstacles that are in the world but not in the map.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Obstacles {
    /// Box edges.
    pub walls: Vec<Wall>,
    /// People: centre and radius.
    pub circles: Vec<(Point2<f64>, f64)>,
}

pub struct Simulator {
    sensor: SensorModel,
    scenario: Scenario,
    caster: RayCaster,
    field: DistanceField,
    bounds: (Point2<f64>, Point2<f64>),
    rng: Rng,
    scratch: RayScratch,
    ideal: Vec<f64>,
    clearance: f64,
    free_space: FreeSpace,
    /// The region of `free_space` poses are drawn from; `None` when no point of the map is
    /// clear and enclosed.
    main_region: Option<u32>,
    count: u64,
    obstacles: Obstacles,
    /// On a walk: every box put so far, kept where it is ([`Simulator::keep_furniture`]).
    kept_boxes: Option<Vec<[Point2<f64>; 4]>>,
}

/// On a walk, boxes are put until this many have their centre within [`BOX_REACH`] of the robot.
const WALK_BOXES: usize = 4;

/// How far from the robot a walk's box counts towards [`WALK_BOXES`], metres: placed boxes are
/// at most 5 m (a wall's distance) plus half a box's depth away.
const BOX_REACH: f64 = 5.5;

impl Simulator {
    pub fn new(map: &WallMap, sensor: SensorModel, scenario: Scenario, seed: u64) -> Self {
        let field = DistanceField::new(&map.walls, 0.05, 1.0);
        let free_space = FreeSpace::new(&field, map.bounds());
        let mut sim = Simulator {
            sensor,
            scenario,
            caster: RayCaster::new(&map.walls),
            field,
            free_space,
            main_region: None,
            bounds: map.bounds(),
            rng: Rng::new(seed),
            scratch: RayScratch::default(),
            ideal: Vec::new(),
            clearance: 0.35,
            count: 0,
            obstacles: Obstacles::default(),
            kept_boxes: None,
        };
        sim.main_region = sim.main_region();
        sim
    }

    /// The region holding most of the lattice points that are clear and enclosed: the
    /// building's main space. 600 points find it (a rack or a closet holds a few % of a map at
    /// most), and each costs a 16-ray cast: on a 5000-wall map they take about 0.1 s.
    fn main_region(&mut self) -> Option<u32> {
        let points: Vec<_> = self.free_space.lattice(600).collect();
        let mut votes = vec![0usize; self.free_space.regions() as usize + 1];
        for q in points {
            if self.field.distance(q) >= self.clearance && self.enclosed(q) {
                if let Some(r) = self.free_space.region(q) {
                    votes[r as usize] += 1;
                }
            }
        }
        let (region, &most) = votes.iter().enumerate().max_by_key(|&(r, &v)| (v, std::cmp::Reverse(r)))?;
        (most > 0).then_some(region as u32)
    }

    pub fn sensor(&self) -> &SensorModel {
        &self.sensor
    }

    /// The obstacles of the last scan.
    pub fn obstacles(&self) -> &Obstacles {
        &self.obstacles
    }

    /// A scan from a random free pose with the scenario's obstacles (scans are 0.1 s apart).
    pub fn next_scan(&mut self) -> LaserScan {
        let p = self.random_pose();
        self.scan_in_scenario(&p)
    }

    /// A scan at `p` among the scenario's obstacles, placed about it.
    fn scan_in_scenario(&mut self, p: &Pose) -> LaserScan {
        let obstacles = match self.scenario {
            Scenario::Clean => Obstacles::default(),
            Scenario::People => self.people(p),
            Scenario::Furniture => self.furniture(p),
        };
        let scan = self.scan_at(p, &obstacles);
        self.obstacles = obstacles;
        scan
    }

    /// A scan from the next pose of a robot walking through the main free space
    /// ([`walk`](Self::walk)), with the scenario's obstacles; the first from a random pose.
    pub fn next_scan_walking(&mut self, from: Option<&Pose>, step: f64) -> LaserScan {
        let p = match from {
            Some(from) => self.walk(from, step),
            None => self.random_pose(),
        };
        self.scan_in_scenario(&p)
    }

    /// Where a robot at `from` is after driving about `step` metres: ahead with a small turn
    /// when the way stays clear of the walls, else after a larger turn (on the spot when no
    /// turn clears the way).
    pub fn walk(&mut self, from: &Pose, step: f64) -> Pose {
        let at = Point2::from(from.translation.vector);
        let heading = from.rotation.angle();
        for attempt in 0..24 {
            let turn = if attempt == 0 {
                0.25 * self.rng.normal()
            } else {
                self.rng.range(-std::f64::consts::PI, std::f64::consts::PI)
            };
            let h = heading + turn;
            let to = at + Vector2::new(h.cos(), h.sin()) * step;
            if self.clear_way(at, to) {
                return pose(to.x, to.y, h);
            }
        }
        pose(at.x, at.y, heading + self.rng.range(-std::f64::consts::PI, std::f64::consts::PI))
    }

    /// Whether the way from `a` to `b` keeps clear of the walls and within the main free space.
    fn clear_way(&self, a: Point2<f64>, b: Point2<f64>) -> bool {
        let steps = ((b - a).norm() / 0.05).ceil().max(1.0) as usize;
        (1..=steps).all(|k| self.room_at(a + (b - a) * (k as f64 / steps as f64)))
    }

    /// Whether the robot fits at `q`: clear of the walls and of the boxes kept on a walk, in
    /// the main free space.
    fn room_at(&self, q: Point2<f64>) -> bool {
        self.field.distance(q) >= self.clearance
            && self.main_region.is_none_or(|main| self.free_space.region(q) == Some(main))
            && self
                .kept_boxes
                .as_ref()
                .is_none_or(|boxes| boxes.iter().flat_map(box_walls).all(|w| w.closest(q).0 >= self.clearance))
    }

    /// From now on, furniture stays where it is put ([`Walk`]): each scan sees the boxes put so
    /// far, and new ones are put only where fewer than `WALK_BOXES` are within reach.
    pub fn keep_furniture(&mut self) {
        self.kept_boxes.get_or_insert_with(Vec::new);
    }

    /// A uniformly drawn pose in the main free space.
    pub fn random_pose(&mut self) -> Pose {
        let (lo, hi) = self.bounds;
        for _ in 0..100_000 {
            let q = Point2::new(self.rng.range(lo.x, hi.x), self.rng.range(lo.y, hi.y));
            if self.room_at(q) && self.enclosed(q) {
                return pose(q.x, q.y, self.rng.range(-std::f64::consts::PI, std::f64::consts::PI));
            }
        }
        // a map with no enclosed free space: any point clear of walls
        pose((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, 0.0)
    }

    /// Whether rays from `q` meet a wall in at least 14 of 16 directions.
    fn enclosed(&mut self, q: Point2<f64>) -> bool {
        let (lo, hi) = self.bounds;
        let reach = (hi - lo).norm() * 2.0 + 1.0;
        let g = ScanGeometry { angle_min: 0.0, angle_increment: TAU / 16.0, range_min: 0.0, range_max: reach };
        self.caster.cast(&pose(q.x, q.y, 0.0), &g, 16, 1, &mut self.scratch, &mut self.ideal);
        self.ideal.iter().filter(|d| d.is_finite()).count() >= 14
    }

    /// Simulates the sensor at pose `p` among `obstacles`.
    pub fn scan_at(&mut self, p: &Pose, obstacles: &Obstacles) -> LaserScan {
        let s = self.sensor;
        let g = s.geometry;
        self.caster.cast(p, &g, s.beams, 1, &mut self.scratch, &mut self.ideal);
        let origin = Point2::from(p.translation.vector);
        let theta = p.rotation.angle();
        for (i, d) in self.ideal.iter_mut().enumerate() {
            let a = theta + g.angle(i);
            let dir = Vector2::new(a.cos(), a.sin());
            for w in &obstacles.walls {
                if let Some(t) = w.ray_hit(origin, dir) {
                    *d = d.min(t);
                }
            }
            for &(c, r) in &obstacles.circles {
                if let Some(t) = ray_circle(origin, dir, c, r) {
                    *d = d.min(t);
                }
            }
        }
        let mut ranges: Vec<f32> = Vec::with_capacity(s.beams);
        for i in 0..s.beams {
            let mut d = self.ideal[i];
            // a mixed pixel: the beam straddles a depth jump and returns something in between
            let neighbour = |k: usize| self.ideal.get(k).copied().unwrap_or(d);
            let other = if (neighbour(i + 1) - d).abs() > (neighbour(i.wrapping_sub(1)) - d).abs() {
                neighbour(i + 1)
            } else {
                neighbour(i.wrapping_sub(1))
            };
            if d.is_finite()
                && other.is_finite()
                && other > d + s.jump
                && other < g.range_max
                && self.rng.chance(s.mixed_pixel * 0.5)
            {
                d += self.rng.range(0.2, 0.8) * (other - d);
            }
            let reading = if !d.is_finite() || d >= g.range_max {
                g.range_max
            } else if self.rng.chance(s.dropout) {
                if s.dropout_reads_max {
                    g.range_max
                } else {
                    0.0
                }
            } else {
                let noisy = d + self.rng.normal() * (s.noise_constant + s.noise_proportional * d);
                if noisy >= g.range_max {
                    g.range_max
                } else {
                    noisy.max(0.0)
                }
            };
            ranges.push(reading as f32);
        }
        let stamp = self.count as f64 * 0.1;
        self.count += 1;
        LaserScan { geometry: g, ranges, stamp, truth: Some(*p) }
    }

    /// A bearing within the field of view, map frame.
    fn bearing_in_view(&mut self, p: &Pose) -> f64 {
        let g = self.sensor.geometry;
        let i = self.rng.range(0.0, (self.sensor.beams - 1) as f64);
        p.rotation.angle() + g.angle_min + i * g.angle_increment
    }

    /// The first wall (map only) along a map-frame bearing.
    fn map_range(&mut self, origin: Point2<f64>, bearing: f64) -> f64 {
        let g = ScanGeometry { angle_min: 0.0, angle_increment: 1.0, range_min: 0.0, range_max: 1e6 };
        self.caster.cast(&pose(origin.x, origin.y, bearing), &g, 1, 1, &mut self.scratch, &mut self.ideal);
        self.ideal[0]
    }

    fn people(&mut self, p: &Pose) -> Obstacles {
        let origin = Point2::from(p.translation.vector);
        let want = self.rng.int(1, 4);
        let mut circles: Vec<(Point2<f64>, f64)> = Vec::new();
        for _ in 0..50 {
            if circles.len() == want {
                break;
            }
            let bearing = self.bearing_in_view(p);
            let dist = self.rng.range(0.6, 3.0);
            let r = self.rng.range(0.1, 0.2);
            let c = origin + Vector2::new(bearing.cos(), bearing.sin()) * dist;
            let free = self.field.distance(c) >= r + 0.05
                && self.map_range(origin, bearing) > dist + r
                && circles.iter().all(|&(o, ro)| (o - c).norm() > r + ro + 0.1);
            if free {
                circles.push((c, r));
            }
        }
        Obstacles { walls: Vec::new(), circles }
    }

    fn furniture(&mut self, p: &Pose) -> Obstacles {
        let origin = Point2::from(p.translation.vector);
        // on a walk: the boxes put before, and new ones until enough are within reach
        let kept = self.kept_boxes.take();
        let walking = kept.is_some();
        let (mut boxes, want) = match kept {
            Some(boxes) => {
                let near = boxes.iter().filter(|b| (centre(b) - origin).norm() <= BOX_REACH).count();
                let want = boxes.len() + WALK_BOXES.saturating_sub(near);
                (boxes, want)
            }
            None => (Vec::new(), self.rng.int(2, 5)),
        };
        for _ in 0..60 {
            if boxes.len() >= want {
                break;
            }
            let bearing = self.bearing_in_view(p);
            let d = self.map_range(origin, bearing);
            if !(1.0..=5.0).contains(&d) {
                continue;
            }
            let hit = origin + Vector2::new(bearing.cos(), bearing.sin()) * d;
            let Some(wall) =
                self.caster.walls().iter().min_by(|a, b| a.closest(hit).0.total_cmp(&b.closest(hit).0)).copied()
            else {
                continue;
            };
            let along = (wall.b - wall.a).normalize();
            let mut normal = Vector2::new(-along.y, along.x);
            if normal.dot(&(origin - hit)) < 0.0 {
                normal = -normal;
            }
            let (width, depth) = (self.rng.range(0.4, 1.6), self.rng.range(0.3, 0.8));
            let centre = hit + normal * (depth / 2.0 + 0.01) + along * self.rng.range(-width / 3.0, width / 3.0);
            let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .map(|(u, v)| centre + along * (u * width / 2.0) + normal * (v * depth / 2.0));
            let clear_of_robot = (centre - origin).norm() > depth.hypot(width) / 2.0 + self.clearance;
            let inside = corners.iter().all(|&c| self.field.distance(c) > 0.005)
                && self.field.distance(centre) >= depth / 2.0 - 0.02;
            let apart = boxes.iter().all(|b| (self::centre(b) - centre).norm() > width.max(depth) + 0.2);
            // a walk's boxes leave the way past them open: a robot fits between a box's front
            // and the walls or boxes across from it
            let passable = !walking || {
                let front = [-1.0, 0.0, 1.0].map(|u| centre + normal * (depth / 2.0) + along * (u * width / 2.0));
                let gap = 2.0 * self.clearance + 0.3;
                front.iter().all(|&f| {
                    self.map_range(f, normal.y.atan2(normal.x)) >= gap
                        && boxes.iter().flat_map(box_walls).all(|w| w.closest(f).0 >= gap)
                })
            };
            if clear_of_robot && inside && apart && passable {
                boxes.push(corners);
            }
        }
        // a scan sees the boxes within its range (and a box's size) of the robot
        let reach = if walking { self.sensor.geometry.range_max + 1.0 } else { f64::INFINITY };
        let walls = boxes.iter().filter(|b| (centre(b) - origin).norm() <= reach).flat_map(box_walls).collect();
        if walking {
            self.kept_boxes = Some(boxes);
        }
        Obstacles { walls, circles: Vec::new() }
    }
}

/// A box's centre.
fn centre(corners: &[Point2<f64>; 4]) -> Point2<f64> {
    corners[0] + (corners[2] - corners[0]) / 2.0
}

/// A box's four edges.
fn box_walls(c: &[Point2<f64>; 4]) -> impl Iterator<Item = Wall> + '_ {
    (0..4).map(move |k| Wall { a: c[k], b: c[(k + 1) % 4] })
}

fn ray_circle(o: Point2<f64>, dir: Vector2<f64>, c: Point2<f64>, r: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(&dir);
    let disc = b * b - (oc.norm_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then_some(t)
}

/// A robot walking through the main free space about `step` metres a scan
/// ([`Simulator::next_scan_walking`]), and its odometry: exact, or drawn by the motion model
/// so that it drifts. `gema2 sim --trajectory` and the acquire stage's `--step` walk it: the
/// same simulator and noise give both the same scans and odometry.
pub struct Walk {
    sim: Simulator,
    step: f64,
    last: Option<Pose>,
    drawn: Option<DriftingOdometry>,
}

impl Walk {
    /// The walk of `sim`, whose seed was `seed`; odometry drawn with `noise`, or exact without.
    pub fn new(mut sim: Simulator, step: f64, noise: Option<OdometryNoise>, seed: u64) -> Self {
        sim.keep_furniture();
        let drawn = noise.map(|n| DriftingOdometry::new(n, seed ^ 0x0D0_0D0));
        Walk { sim, step, last: None, drawn }
    }

    /// The next scan and the odometry at it.
    pub fn next_scan(&mut self) -> (LaserScan, Option<Pose>) {
        let scan = self.sim.next_scan_walking(self.last.as_ref(), self.step);
        self.last = scan.truth;
        let odometry = match (self.drawn.as_mut(), scan.truth.as_ref()) {
            (Some(drawn), Some(truth)) => Some(drawn.next(truth, false)),
            _ => scan.truth,
        };
        (scan, odometry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clean_scans_match_ray_casting_within_the_noise() {
        let map = worlds::apartment();
        let mut model = SensorModel::urg04lx();
        model.dropout = 0.0;
        model.mixed_pixel = 0.0;
        let mut sim = Simulator::new(&map, model, Scenario::Clean, 3);
        let caster = RayCaster::new(&map.walls);
        for _ in 0..20 {
            let scan = sim.next_scan();
            let truth = scan.truth.unwrap();
            let q = Point2::from(truth.translation.vector);
            assert!(map.walls.iter().all(|w| w.closest(q).0 >= 0.35));
            let mut ideal = Vec::new();
            caster.cast(&truth, &scan.geometry, scan.ranges.len(), 1, &mut RayScratch::default(), &mut ideal);
            for (r, d) in scan.ranges.iter().zip(&ideal) {
                if *d < 5.0 {
                    assert!((*r as f64 - d).abs() < 6.0 * (0.01 + 0.005 * d), "{r} vs {d}");
                }
            }
        }
    }

    #[test]
    fn scenarios_place_their_obstacles_near_the_robot() {
        let map = worlds::office(1, 2, 8);
        let mut sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::People, 9);
        let mut people = 0;
        for _ in 0..30 {
            let scan = sim.next_scan();
            let o = Point2::from(scan.truth.unwrap().translation.vector);
            for &(c, r) in &sim.obstacles().circles {
                assert!((c - o).norm() <= 3.0 + 1e-9 && (0.1..=0.2).contains(&r));
                people += 1;
            }
        }
        assert!(people >= 30, "{people}");
        let mut sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::Furniture, 9);
        let mut boxes = 0;
        for _ in 0..30 {
            sim.next_scan();
            boxes += sim.obstacles().walls.len() / 4;
        }
        assert!(boxes >= 30, "{boxes}");
    }

    #[test]
    fn poses_are_never_inside_a_closed_outline() {
        // a hall with a closed 4 x 4 m block: before poses kept to the main region, about a
        // quarter of them fell inside the block
        let mut walls = Wall::rectangle(0.0, 0.0, 10.0, 6.0).to_vec();
        walls.extend(Wall::rectangle(3.0, 1.0, 7.0, 5.0));
        let map = WallMap::new(walls);
        let mut sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::Clean, 4);
        for _ in 0..300 {
            let q = sim.random_pose().translation.vector;
            assert!(!((3.0..=7.0).contains(&q.x) && (1.0..=5.0).contains(&q.y)), "pose inside the block: {q}");
        }
    }

    /// A walk keeps clear of the walls, within the main free space, a step at a time, and
    /// gets somewhere.
    #[test]
    fn a_walk_keeps_clear_of_the_walls() {
        let map = worlds::by_name("office").unwrap();
        let mut sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::Clean, 9);
        let start = sim.random_pose();
        let mut at = start;
        let mut furthest: f64 = 0.0;
        for _ in 0..300 {
            let next = sim.walk(&at, 0.2);
            let (a, b) = (Point2::from(at.translation.vector), Point2::from(next.translation.vector));
            assert!((b - a).norm() <= 0.2 + 1e-9);
            assert!(sim.clear_way(a, b) || a == b, "{a} to {b}");
            furthest = furthest.max((b - Point2::from(start.translation.vector)).norm());
            at = next;
        }
        assert!(furthest > 3.0, "the walk stayed within {furthest} m");
    }

    /// On a walk the furniture stays where it was put: a box seen once is seen again while the
    /// robot is near it, the robot keeps clear of every box, and new boxes come as it moves on.
    #[test]
    fn a_walk_s_furniture_stays_put_and_the_walk_goes_around_it() {
        let map = worlds::by_name("warehouse").unwrap();
        let sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::Furniture, 7);
        let mut walk = Walk::new(sim, 0.5, None, 7);
        let mut seen: Vec<Wall> = Vec::new();
        let mut kept_seen = 0;
        for _ in 0..200 {
            let (scan, _) = walk.next_scan();
            let at = Point2::from(scan.truth.unwrap().translation.vector);
            let now = &walk.sim.obstacles().walls;
            for w in now {
                assert!(w.closest(at).0 >= walk.sim.clearance - 1e-9, "the robot at {at} is in a box");
            }
            // every box seen before whose centre is within the sensor's range is still there
            for w in seen.iter().filter(|w| (w.a - at).norm() < 4.0) {
                assert!(now.contains(w), "a box moved: {w:?}");
                kept_seen += 1;
            }
            for w in now {
                if !seen.contains(w) {
                    seen.push(*w);
                }
            }
        }
        assert!(kept_seen > 100, "boxes were seen again only {kept_seen} times");
        assert!(seen.len() / 4 > 8, "only {} boxes over the walk", seen.len() / 4);
    }

    #[test]
    fn same_seed_same_log() {
        let map = worlds::apartment();
        let mut a = Simulator::new(&map, SensorModel::urg04lx(), Scenario::People, 5);
        let mut b = Simulator::new(&map, SensorModel::urg04lx(), Scenario::People, 5);
        for _ in 0..5 {
            assert_eq!(a.next_scan(), b.next_scan());
        }
    }
}
