//! The map server process: loads the map and builds its model once per version
//! ([`map::MapModel`]: corners sorted by inner angle, wall grids, distance field, free space),
//! then publishes the model on `gema2/map/model` and the walls on `gema2/map`, both with
//! history, so a localizer that starts, restarts or is swapped in later reads the model in
//! place at once. It answers corner queries on `gema2/map/corners` (inner angle and tolerance,
//! optionally within a region) from the model, and reloads the map when its file (or a ROS
//! map's image) changes or on SIGHUP, publishing a new version. The model's corner settings
//! are the pipeline's (`--set`, as the localizer's); a localizer with others refuses it.

use anyhow::{bail, Context, Result};
use clap::Args;
use map::model::MODEL_LAYOUT;
use map::MapModel;
use mapio::load_map_with_grid;
use messages::iceoryx2::port::update_connections::UpdateConnections;
use messages::iceoryx2::service::port_factory::PortFactory as _;
use messages::{
    open_corner_queries, open_model_topic, open_topic, publish, CornerQuery, CornerReply, MapCornerMsg, MapMsg,
    ModelOutlet, Topic, MAX_CORNERS, MAX_WALLS,
};
use nalgebra::Point2;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime};

/// What the stage is, for its `--help` (its own program's and `gema2 stage mapserver`'s).
pub const ABOUT: &str = "GEMA2 map server: the map and its model with history, corner queries, reload on change";

#[derive(Args, Debug, Clone)]
pub struct MapServerArgs {
    #[command(flatten)]
    pub stage: messages::StageArgs,
    /// A bundled map's name, a JSON wall map or a ROS map_server .yaml (watched for changes), or
    /// `ros2:/map`: the nav_msgs/OccupancyGrid a ROS 2 map_server publishes on that topic (DDS
    /// domain $ROS_DOMAIN_ID), each grid a new version.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// A setting, KEY=VALUE (repeatable), as the localizer's `--set`: the map-corner keys
    /// (`gema2 settings`) shape the model, and must be the localizers' too.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

static RELOAD: AtomicBool = AtomicBool::new(false);

extern "C" fn on_sighup(_: libc::c_int) {
    RELOAD.store(true, Ordering::Relaxed);
}

/// When the map's files last changed: a ROS map's YAML file or the image it names.
/// The files a map is read from and when they last changed: what the server watches. The
/// YAML of a ROS map is read once here, for the image it names, not at every look (it was read
/// every 5 ms); a look only asks the file system for the files' times, and at most every
/// [`LOOK_EVERY`].
struct Watched {
    files: Vec<std::path::PathBuf>,
    stamp: Option<SystemTime>,
    looked: std::time::Instant,
}

/// How often the map's files are looked at for a change.
const LOOK_EVERY: Duration = Duration::from_millis(250);

impl Watched {
    fn of(spec: &str) -> Self {
        let path = Path::new(spec);
        let files = if mapio::ros::is_ros_map(path) { mapio::ros::files_of(path) } else { vec![path.to_owned()] };
        let stamp = Self::newest(&files);
        Watched { files, stamp, looked: std::time::Instant::now() }
    }

    fn newest(files: &[std::path::PathBuf]) -> Option<SystemTime> {
        files.iter().filter_map(|f| std::fs::metadata(f).and_then(|m| m.modified()).ok()).max()
    }

    /// Whether a file changed since the last look that said so (at most every [`LOOK_EVERY`]).
    fn changed(&mut self) -> bool {
        if self.looked.elapsed() < LOOK_EVERY {
            return false;
        }
        self.looked = std::time::Instant::now();
        let now = Self::newest(&self.files);
        std::mem::replace(&mut self.stamp, now) != now
    }
}

/// A map version: the map and its model, built with `config`'s corner settings (the model
/// answers the corner queries), and what its block and build took.
struct Version {
    model: MapModel,
    block_len: usize,
    built_in: Duration,
    /// How a rough grid's walls were made, said beside the model.
    walls_from: Option<String>,
}

/// The map version `spec` names, and its model as the block to publish once.
fn load(spec: &str, config: &localize::Gema2Config) -> Result<(Version, map::flat::FlatWriter)> {
    let started = std::time::Instant::now();
    let (map, grid) = load_map_with_grid(spec)?;
    let (mut version, block) = build(map, spec, config)?;
    if let Some(mapio::GridWalls::Surveyed { scans, .. }) = grid {
        let took = started.elapsed().saturating_sub(version.built_in).as_secs_f64();
        version.walls_from =
            Some(format!("; walls built from {scans} scans of a virtual laser in the rough grid in {took:.1} s"));
    }
    Ok((version, block))
}

/// The version of `map` (named `spec` in errors), and its model as the block to publish once.
fn build(map: map::WallMap, spec: &str, config: &localize::Gema2Config) -> Result<(Version, map::flat::FlatWriter)> {
    if map.walls.len() > MAX_WALLS {
        bail!("{spec}: {} walls, at most {MAX_WALLS} can be published", map.walls.len());
    }
    let started = std::time::Instant::now();
    let model = MapModel::new(map, &config.map_corners);
    let block = model.to_block();
    Ok((Version { model, block_len: block.len(), built_in: started.elapsed(), walls_from: None }, block))
}

/// A map from a ROS 2 map_server: the grids as they come.
struct RosMap {
    topic: String,
    grids: std::sync::mpsc::Receiver<Result<map::WallMap>>,
    stop: std::sync::Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RosMap {
    fn start(topic: &str) -> Result<Self> {
        let domain = ros::domain_id(None).map_err(anyhow::Error::msg)?;
        let (tx, grids) = std::sync::mpsc::channel();
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let thread = crate::ros_map::subscribe(topic, domain, tx, std::sync::Arc::clone(&stop))?;
        Ok(RosMap { topic: topic.to_owned(), grids, stop, thread: Some(thread) })
    }

    /// The first grid that gives a map: a map server is ready only with one.
    fn first(&self) -> Result<map::WallMap> {
        messages::say!("mapserver: waiting for a nav_msgs/OccupancyGrid on {}", self.topic);
        loop {
            match self.grids.recv() {
                Ok(Ok(map)) => return Ok(map),
                Ok(Err(e)) => messages::say!("mapserver: {}: {e:#}; waiting for another", self.topic),
                Err(_) => bail!("{}: the map subscription ended", self.topic),
            }
        }
    }
}

impl Drop for RosMap {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The answer to a corner query `q` from `index` (the map of `version`): the corners of
/// similar inner angle, within the query's region when it gives one, as many as fit, and how
/// many there were.
fn corner_reply(index: &map::CornerIndex, version: u32, q: &CornerQuery) -> CornerReply {
    let mut reply = CornerReply {
        map_version: version,
        count: 0,
        total: 0,
        _pad: 0,
        corners: [MapCornerMsg::default(); MAX_CORNERS],
    };
    let centre = Point2::new(q.x, q.y);
    let found = index
        .similar(q.inner_angle, q.tolerance.abs())
        .iter()
        .filter(|c| q.has_region == 0 || (c.position - centre).norm() <= q.radius);
    for c in found {
        if (reply.count as usize) < MAX_CORNERS {
            reply.corners[reply.count as usize] = MapCornerMsg {
                position: [c.position.x, c.position.y],
                inner_angle: c.inner_angle,
                orientation: c.orientation,
            };
            reply.count += 1;
        }
        reply.total += 1;
    }
    reply
}

/// How long a map server waits for the version another one serves.
const RUNNING_VERSION_PATIENCE: Duration = Duration::from_secs(2);

/// The map version another map server under this prefix serves, when one does (this one has
/// published nothing yet).
fn running_version(
    node: &messages::iceoryx2::prelude::Node<messages::iceoryx2::prelude::ipc::Service>,
    topic: &messages::TopicPorts<MapMsg>,
) -> Result<Option<u32>> {
    if topic.data.dynamic_config().number_of_publishers() <= 1 {
        return Ok(None);
    }
    let subscriber = topic.data.subscriber_builder().create().with_context(|| format!("{}: subscriber", topic.name))?;
    let deadline = std::time::Instant::now() + RUNNING_VERSION_PATIENCE;
    while std::time::Instant::now() < deadline {
        // the other server hands its history over from its loop, every few milliseconds
        if let Some(sample) = subscriber.receive().map_err(|e| anyhow::anyhow!("{}: receive: {e:?}", topic.name))? {
            return Ok(Some(sample.version));
        }
        if !messages::sleep(node, Duration::from_millis(5)) {
            break;
        }
    }
    Ok(None)
}

pub fn run(a: MapServerArgs) -> Result<()> {
    let mut config = localize::Gema2Config::default();
    config.apply(&a.set).context("mapserver: --set")?;
    a.stage.place()?;
    // SAFETY: the handler only stores to an atomic.
    unsafe { libc::signal(libc::SIGHUP, on_sighup as *const () as libc::sighandler_t) };
    let from_ros = match crate::ros_map::topic_of(&a.map) {
        Some(topic) => Some(RosMap::start(topic)?),
        None => None,
    };
    let (mut current, block) = match &from_ros {
        Some(ros) => build(ros.first()?, &a.map, &config)?,
        None => load(&a.map, &config)?,
    };
    let mut watched = Watched::of(&a.map);
    let node = messages::create_node("mapserver")?;
    let topic = open_topic::<MapMsg>(&node, &a.stage.prefix, Topic::Map)?;
    let publisher = topic.data.publisher_builder().create().with_context(|| format!("{}: publisher", topic.name))?;
    let notifier = topic.event.notifier_builder().create().with_context(|| format!("{}: notifier", topic.name))?;
    let model_topic = open_model_topic(&node, &a.stage.prefix)?;
    let mut model_out = ModelOutlet::new(&model_topic, current.block_len)?;
    let model_notifier =
        model_topic.event.notifier_builder().create().with_context(|| format!("{}: notifier", model_topic.name))?;
    let queries = open_corner_queries(&node, &a.stage.prefix)?;
    let server = queries.server_builder().create().context("corner queries: server")?;
    // a map server this one replaces (a hot swap) has published some version: go on from it,
    // so the localizers take this one's map as a new version
    let mut version = running_version(&node, &topic)?.map_or(1, |v| v.wrapping_add(1).max(1));
    // the model first: a localizer that sees the walls' new version finds its model there
    let send = |model_out: &mut ModelOutlet, v: &Version, block: map::flat::FlatWriter, version: u32| -> Result<()> {
        model_out.publish(&model_topic, &model_notifier, version, MODEL_LAYOUT, block.bytes())?;
        let mut written = Ok(());
        let sent = publish(&publisher, &notifier, |m: &mut MapMsg| {
            written = crate::wire::map_to_msg(&v.model.map, version, m)
        });
        written
            .map_err(anyhow::Error::from)
            .and(sent.map(|_| ()).map_err(anyhow::Error::from))
            .with_context(|| topic.name.clone())
    };
    send(&mut model_out, &current, block, version)?;
    messages::announce_ready(&node, &a.stage.prefix)?;
    let said = |v: &Version, what: &str, version: u32| {
        messages::say!(
            "mapserver: {what} {} ({} walls, {} corners) as version {version}: model of {:.1} MB built in {:.2} s{}",
            a.map,
            v.model.map.walls.len(),
            v.model.corners.corners().len(),
            v.block_len as f64 / 1e6,
            v.built_in.as_secs_f64(),
            v.walls_from.as_deref().unwrap_or_default()
        )
    };
    said(&current, "serving", version);
    let mut model_readers = 0;
    // queries and late joiners are served every few milliseconds; the data path never waits here
    while messages::sleep(&node, Duration::from_millis(5)) {
        publisher.update_connections().with_context(|| topic.name.clone())?;
        model_out.update_connections(&model_topic)?;
        // a reader that joined was just handed the history, with no wake-up of its own: wake it
        let readers = model_topic.data.dynamic_config().number_of_subscribers();
        if readers > model_readers {
            model_notifier.notify().with_context(|| model_topic.name.clone())?;
        }
        model_readers = readers;
        while let Some(request) = server.receive().context("corner queries")? {
            let q = *request.payload();
            let response = request.loan_uninit().context("corner queries: loan")?;
            let reply = corner_reply(&current.model.corners, version, &q);
            response.write_payload(reply).send().context("corner queries: send")?;
        }
        // new versions: the grids that came from ROS, or the file changed (or SIGHUP)
        let reload = RELOAD.swap(false, Ordering::Relaxed);
        let arrived: Vec<(&str, Result<(Version, map::flat::FlatWriter)>)> = match &from_ros {
            Some(ros) => {
                ros.grids.try_iter().map(|g| ("received", g.and_then(|map| build(map, &a.map, &config)))).collect()
            }
            None if reload || watched.changed() => {
                // the YAML may name another image now
                watched = Watched::of(&a.map);
                vec![("reloaded", load(&a.map, &config))]
            }
            None => Vec::new(),
        };
        for (what, next) in arrived {
            match next {
                Ok((v, block)) => {
                    version += 1;
                    current = v;
                    send(&mut model_out, &current, block, version)?;
                    said(&current, what, version);
                }
                Err(e) => messages::say!("mapserver: kept version {version}: {e:#}"),
            }
        }
    }
    Ok(())
}
