//! rosbag2 files in sqlite3 storage (`.db3`, ROS 2 Humble's default): the `topics` table names
//! each topic and its type, the `messages` table holds the CDR bytes in the order they were
//! recorded (by row id). Read a page of rows at a time, never the whole file.

use crate::stored::{BagError, BagMessage, Encoding, TopicInfo};
use rusqlite::{Connection, OpenFlags};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Rows read per query.
const PAGE: i64 = 256;

fn error(path: &Path, e: impl std::fmt::Display) -> BagError {
    BagError::Sqlite { path: path.to_owned(), cause: e.to_string() }
}

fn open(path: &Path) -> Result<Connection, BagError> {
    Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX)
        .map_err(|e| error(path, e))
}

/// Topic id -> name and type.
type Topics = HashMap<i64, (Arc<str>, Arc<str>)>;

fn topic_table(c: &Connection, path: &Path) -> Result<Topics, BagError> {
    let mut q = c.prepare("SELECT id, name, type FROM topics").map_err(|e| error(path, e))?;
    let rows = q
        .query_map([], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, String>(1)?, r.get::<_, String>(2)?)))
        .map_err(|e| error(path, e))?;
    let mut topics = HashMap::new();
    for row in rows {
        let (id, name, ros_type) = row.map_err(|e| error(path, e))?;
        topics.insert(id, (Arc::from(name), Arc::from(ros_type)));
    }
    Ok(topics)
}

/// The topics of a `.db3` file with their message counts.
pub fn topics(path: &Path) -> Result<Vec<TopicInfo>, BagError> {
    let c = open(path)?;
    let names = topic_table(&c, path)?;
    let mut q = c.prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id").map_err(|e| error(path, e))?;
    let counts: HashMap<i64, u64> = q
        .query_map([], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?.max(0) as u64)))
        .map_err(|e| error(path, e))?
        .collect::<Result<_, _>>()
        .map_err(|e| error(path, e))?;
    Ok(names
        .iter()
        .map(|(id, (name, ros_type))| TopicInfo {
            name: name.to_string(),
            ros_type: ros_type.to_string(),
            messages: Some(counts.get(id).copied().unwrap_or(0)),
        })
        .collect())
}

/// One `.db3` file read in row order.
pub struct Db3File {
    path: PathBuf,
    connection: Connection,
    topics: Topics,
    wanted: Vec<String>,
    /// The last row id read, and the rows read but not yet returned.
    after: i64,
    page: std::collections::VecDeque<BagMessage>,
    done: bool,
}

impl Db3File {
    pub fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
        let connection = open(path)?;
        let topics = topic_table(&connection, path)?;
        Ok(Db3File {
            path: path.to_owned(),
            connection,
            topics,
            wanted,
            after: i64::MIN,
            page: Default::default(),
            done: false,
        })
    }

    /// The next wanted message, `None` at the end of the file.
    pub fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
        while self.page.is_empty() && !self.done {
            self.read_page()?;
        }
        Ok(self.page.pop_front())
    }

    fn read_page(&mut self) -> Result<(), BagError> {
        let path = &self.path;
        let mut q = self
            .connection
            .prepare_cached("SELECT id, topic_id, timestamp, data FROM messages WHERE id > ?1 ORDER BY id LIMIT ?2")
            .map_err(|e| error(path, e))?;
        let rows = q
            .query_map([self.after, PAGE], |r| {
                Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?, r.get::<_, i64>(2)?, r.get::<_, Vec<u8>>(3)?))
            })
            .map_err(|e| error(path, e))?;
        let mut read = 0;
        for row in rows {
            let (id, topic, time, data) = row.map_err(|e| error(path, e))?;
            read += 1;
            self.after = id;
            let Some((name, ros_type)) = self.topics.get(&topic) else {
                return Err(error(path, format!("message {id} names topic {topic}, which the topics table lacks")));
            };
            if self.wanted.is_empty() || self.wanted.iter().any(|w| **w == **name) {
                self.page.push_back(BagMessage {
                    topic: Arc::clone(name),
                    ros_type: Arc::clone(ros_type),
                    log_time: time.max(0) as u64,
                    data,
                    encoding: Encoding::Cdr,
                });
            }
        }
        self.done = read < PAGE;
        Ok(())
    }
}
