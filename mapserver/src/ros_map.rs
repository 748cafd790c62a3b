//! A map taken from a ROS 2 map_server over DDS (`--map ros2:/map`): the
//! `nav_msgs/OccupancyGrid` it publishes (reliable, transient local: the latest one reaches a
//! late subscriber) is made into walls as a map_server YAML map is ([`mapio::grid_walls`]), and
//! each grid becomes a map version. A grid that cannot be is reported and the server keeps what
//! it serves.

use anyhow::{anyhow, Result};
use map::WallMap;
use mapio::ros::OccupancyGrid;
use ros::msg;
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::{Context, ContextOptions, Subscription};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::Duration;

/// What `--map` says for a map from ROS: `ros2:` and the topic (`/map` when empty).
pub const PREFIX: &str = "ros2:";

/// The topic a `--map` names, when it names one.
pub fn topic_of(spec: &str) -> Option<&str> {
    spec.strip_prefix(PREFIX).map(|t| if t.is_empty() { "/map" } else { t })
}

/// The wall map of a grid message, or why it has none.
pub fn wall_map(m: &msg::OccupancyGrid) -> Result<WallMap> {
    let i = &m.info;
    let (x, y, yaw) = i.origin.planar();
    let grid =
        OccupancyGrid::from_occupancy(i.resolution as f64, [x, y, yaw], i.width as usize, i.height as usize, &m.data)
            .ok_or_else(|| {
            anyhow!(
                "a grid of {} x {} cells at {} m with {} values: not a usable map",
                i.width,
                i.height,
                i.resolution,
                m.data.len()
            )
        })?;
    mapio::grid_walls(&grid).map(|(map, _)| map).map_err(|e| anyhow!("making the grid into walls: {e}"))
}

/// Starts the thread that takes grids from `topic` (DDS domain `domain`) and sends each one's
/// wall map, or why it has none, until `stop`.
pub fn subscribe(
    topic: &str,
    domain: u16,
    out: Sender<Result<WallMap>>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>> {
    let name = Name::parse(topic).map_err(|e| anyhow!("{topic}: not a ROS topic name: {e:?}"))?;
    let context = Context::with_options(ContextOptions::new().domain_id(domain))
        .map_err(|e| anyhow!("starting DDS (domain {domain}): {e:?}"))?;
    let mut node = context
        .new_node(NodeName::new("/", "gema2_map").map_err(|e| anyhow!("{e:?}"))?, NodeOptions::new())
        .map_err(|e| anyhow!("creating the ROS node: {e:?}"))?;
    let latched = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 });
    let t = node
        .create_topic(&name, MessageTypeName::new("nav_msgs", "OccupancyGrid"), &latched)
        .map_err(|e| anyhow!("{topic}: {e:?}"))?;
    let mut grids: Subscription<msg::OccupancyGrid> =
        node.create_subscription(&t, None).map_err(|e| anyhow!("{topic}: {e:?}"))?;
    let thread = std::thread::Builder::new().name("map-in".into()).spawn(move || {
        // the node and context live as long as the subscription
        let (_node, _context) = (node, context);
        let Ok(mut poll) = Poll::new() else { return };
        if poll.registry().register(&mut grids, Token(0), Interest::READABLE).is_err() {
            return;
        }
        let mut events = Events::with_capacity(4);
        while !stop.load(Ordering::Relaxed) {
            let _ = poll.poll(&mut events, Some(Duration::from_millis(100)));
            while let Some(taken) = grids.take().transpose() {
                let map =
                    taken.map_err(|e| anyhow!("a grid that does not decode: {e:?}")).and_then(|(m, _)| wall_map(&m));
                if out.send(map).is_err() {
                    return;
                }
            }
        }
    })?;
    Ok(thread)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_message_becomes_walls_and_a_bad_one_says_why() {
        // a 2 m room of 0.1 m cells: a ring of occupied cells round free ones
        let n = 20;
        let data: Vec<i8> = (0..n * n)
            .map(|k| {
                let (i, j) = (k % n, k / n);
                if i == 0 || j == 0 || i == n - 1 || j == n - 1 {
                    100
                } else {
                    0
                }
            })
            .collect();
        let mut m = msg::OccupancyGrid { data, ..Default::default() };
        m.info.resolution = 0.1;
        (m.info.width, m.info.height) = (n as u32, n as u32);
        m.info.origin = msg::Pose::from_planar(-1.0, -1.0, 0.0);
        let map = wall_map(&m).unwrap();
        assert!(map.walls.len() >= 4, "{:?}", map.walls);
        let (lo, hi) = map.bounds();
        assert!(lo.x >= -1.01 && hi.x <= 1.01, "{lo} {hi}");
        m.data.pop();
        assert!(wall_map(&m).unwrap_err().to_string().contains("not a usable map"));
        assert_eq!(topic_of("ros2:"), Some("/map"));
        assert_eq!(topic_of("ros2:/floor2/map"), Some("/floor2/map"));
        assert_eq!(topic_of("office"), None);
    }
}
