//! rosbag2 bags in MCAP storage, read in bag order without loading them whole: a bag
//! directory (its `metadata.yaml` names the files, in order) or a single `.mcap` file. Each
//! message comes with its topic and its ROS type (`sensor_msgs/msg/LaserScan`); the bytes are
//! CDR ([`crate::msg`]).
//!
//! A bag in sqlite3 storage is refused with the command that converts it. A file that stops
//! making sense (cut short, a bad chunk) ends the reading there with an error naming it; the
//! messages before it have been returned.

use mcap::sans_io::{LinearReadEvent, LinearReader, SummaryReadEvent, SummaryReader};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum BagError {
    // the cause in the message, not chained too: it would print twice
    #[error("{path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: not a readable MCAP file: {cause}")]
    Mcap { path: PathBuf, cause: String },
    #[error(
        "{path}: a bag in {storage} storage; gema2 reads MCAP bags: convert it with `ros2 bag convert` or \
         `rosbags-convert --dst-storage mcap`"
    )]
    Storage { path: PathBuf, storage: String },
    #[error("{path}: not a bag: neither a directory with metadata.yaml nor an .mcap file")]
    NotABag { path: PathBuf },
    #[error("{path}: the bag's metadata.yaml names no data file")]
    NoFiles { path: PathBuf },
}

/// A topic of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicInfo {
    pub name: String,
    /// The ROS type, e.g. `sensor_msgs/msg/LaserScan`.
    pub ros_type: String,
    /// Messages on it, when the files' summaries say.
    pub messages: Option<u64>,
}

/// One message of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BagMessage {
    pub topic: Arc<str>,
    pub ros_type: Arc<str>,
    /// When the recorder received it, ns since the epoch.
    pub log_time: u64,
    /// The message, CDR.
    pub data: Vec<u8>,
}

/// A bag: its data files, in order.
#[derive(Clone, Debug)]
pub struct Bag {
    pub path: PathBuf,
    pub files: Vec<PathBuf>,
}

impl Bag {
    /// The bag at `path`: a directory holding `metadata.yaml`, or one `.mcap` file.
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let io = |cause| BagError::Io { path: path.to_owned(), cause };
        if path.is_dir() {
            let meta = path.join("metadata.yaml");
            let text = std::fs::read_to_string(&meta).map_err(|cause| {
                if cause.kind() == std::io::ErrorKind::NotFound {
                    BagError::NotABag { path: path.to_owned() }
                } else {
                    BagError::Io { path: meta.clone(), cause }
                }
            })?;
            let (storage, names) = read_metadata(&text);
            if storage.as_deref().is_some_and(|s| s != "mcap") {
                return Err(BagError::Storage { path: path.to_owned(), storage: storage.unwrap_or_default() });
            }
            if names.is_empty() {
                return Err(BagError::NoFiles { path: path.to_owned() });
            }
            let files: Vec<PathBuf> = names.iter().map(|n| path.join(n)).collect();
            if let Some(f) = files.iter().find(|f| f.extension().is_some_and(|e| e == "db3")) {
                return Err(BagError::Storage { path: f.clone(), storage: "sqlite3".into() });
            }
            return Ok(Bag { path: path.to_owned(), files });
        }
        std::fs::metadata(path).map_err(io)?;
        match path.extension().and_then(|e| e.to_str()) {
            Some("mcap") => Ok(Bag { path: path.to_owned(), files: vec![path.to_owned()] }),
            Some("db3") => Err(BagError::Storage { path: path.to_owned(), storage: "sqlite3".into() }),
            _ => Err(BagError::NotABag { path: path.to_owned() }),
        }
    }

    /// Bytes in the bag's files (for progress).
    pub fn size(&self) -> u64 {
        self.files.iter().filter_map(|f| std::fs::metadata(f).ok()).map(|m| m.len()).sum()
    }

    /// Every topic of the bag with its type, from the files' summaries (a file without one is
    /// read through).
    pub fn topics(&self) -> Result<Vec<TopicInfo>, BagError> {
        let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
        for file in &self.files {
            for t in file_topics(file)? {
                let entry = topics.entry(t.name.clone()).or_insert(TopicInfo { messages: Some(0), ..t.clone() });
                entry.messages = entry.messages.zip(t.messages).map(|(a, b)| a + b);
            }
        }
        Ok(topics.into_values().collect())
    }

    /// The messages on `topics` (every topic when empty), in bag order.
    pub fn messages(&self, topics: &[&str]) -> Messages {
        Messages {
            files: self.files.clone().into_iter(),
            current: None,
            wanted: topics.iter().map(|t| t.to_string()).collect(),
            failed: false,
        }
    }
}

/// `storage_identifier` and `relative_file_paths` of a rosbag2 `metadata.yaml`. The file is
/// YAML written by rosbag2 in one layout; only these two keys are read.
fn read_metadata(text: &str) -> (Option<String>, Vec<String>) {
    let value = |l: &str| l.split_once(':').map(|(_, v)| v.trim().trim_matches(|c| c == '"' || c == '\'').to_owned());
    let mut storage = None;
    let mut files = Vec::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let key = line.trim_start();
        if key.starts_with("storage_identifier:") {
            storage = value(key);
        } else if key.starts_with("relative_file_paths:") {
            while let Some(item) = lines.peek().and_then(|l| l.trim_start().strip_prefix("- ")) {
                files.push(item.trim().trim_matches(|c| c == '"' || c == '\'').to_owned());
                lines.next();
            }
        }
    }
    (storage, files)
}

fn mcap_error(path: &Path, e: impl std::fmt::Display) -> BagError {
    BagError::Mcap { path: path.to_owned(), cause: e.to_string() }
}

/// The topics of one MCAP file, from its summary or, without one (a file cut short, a writer
/// that wrote none), by reading it through: as far as it reads, when that finds any.
fn file_topics(path: &Path) -> Result<Vec<TopicInfo>, BagError> {
    if let Some(summary) = file_summary(path)?.filter(|s| !s.channels.is_empty()) {
        let counts = summary.stats.as_ref().map(|s| &s.channel_message_counts);
        return Ok(summary
            .channels
            .values()
            .map(|c| TopicInfo {
                name: c.topic.clone(),
                ros_type: c.schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
                messages: counts.map(|m| m.get(&c.id).copied().unwrap_or(0)),
            })
            .collect());
    }
    let mut stream = McapFile::open(path, Vec::new())?;
    let mut counts: BTreeMap<(Arc<str>, Arc<str>), u64> = BTreeMap::new();
    let mut whole = true;
    loop {
        match stream.next_message() {
            Ok(Some(m)) => *counts.entry((m.topic, m.ros_type)).or_default() += 1,
            Ok(None) => break,
            // reading the messages will meet this error again, after those before it
            Err(_) if !counts.is_empty() => {
                whole = false;
                break;
            }
            Err(e) => return Err(e),
        }
    }
    Ok(counts
        .into_iter()
        .map(|((name, ros_type), n)| TopicInfo {
            name: name.to_string(),
            ros_type: ros_type.to_string(),
            messages: whole.then_some(n),
        })
        .collect())
}

/// The summary section of an MCAP file; `None` when it has none or it cannot be read.
fn file_summary(path: &Path) -> Result<Option<mcap::Summary>, BagError> {
    let io = |cause| BagError::Io { path: path.to_owned(), cause };
    let mut file = File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    let mut reader =
        SummaryReader::new_with_options(mcap::sans_io::SummaryReaderOptions::default().with_file_size(size));
    while let Some(event) = reader.next_event() {
        match event {
            Ok(SummaryReadEvent::ReadRequest(need)) => {
                let n = file.read(reader.insert(need)).map_err(io)?;
                reader.notify_read(n);
            }
            Ok(SummaryReadEvent::SeekRequest(to)) => reader.notify_seeked(file.seek(to).map_err(io)?),
            Err(_) => return Ok(None),
        }
    }
    Ok(reader.finish())
}

/// One MCAP file read from start to end.
struct McapFile {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    schemas: HashMap<u16, Arc<str>>,
    /// Channel id -> topic and type.
    channels: HashMap<u16, (Arc<str>, Arc<str>)>,
    wanted: Vec<String>,
}

impl McapFile {
    fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
        let file = File::open(path).map_err(|cause| BagError::Io { path: path.to_owned(), cause })?;
        Ok(McapFile {
            path: path.to_owned(),
            file,
            reader: LinearReader::new(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            wanted,
        })
    }

    /// The next wanted message, `None` at the end of the file.
    fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
        while let Some(event) = self.reader.next_event() {
            let record = match event.map_err(|e| mcap_error(&self.path, e))? {
                LinearReadEvent::ReadRequest(need) => {
                    let n = self
                        .file
                        .read(self.reader.insert(need))
                        .map_err(|cause| BagError::Io { path: self.path.clone(), cause })?;
                    self.reader.notify_read(n);
                    continue;
                }
                LinearReadEvent::Record { opcode, data } => {
                    mcap::parse_record(opcode, data).map_err(|e| mcap_error(&self.path, e))?
                }
            };
            match record {
                mcap::records::Record::Schema { header, .. } => {
                    self.schemas.insert(header.id, header.name.into());
                }
                mcap::records::Record::Channel(c) => {
                    let ros_type = self.schemas.get(&c.schema_id).cloned().unwrap_or_else(|| "".into());
                    self.channels.insert(c.id, (c.topic.into(), ros_type));
                }
                mcap::records::Record::Message { header, data } => {
                    let Some((topic, ros_type)) = self.channels.get(&header.channel_id) else {
                        return Err(mcap_error(
                            &self.path,
                            format!("a message on channel {} before that channel's record", header.channel_id),
                        ));
                    };
                    if self.wanted.is_empty() || self.wanted.iter().any(|w| **w == **topic) {
                        return Ok(Some(BagMessage {
                            topic: Arc::clone(topic),
                            ros_type: Arc::clone(ros_type),
                            log_time: header.log_time,
                            data: data.into_owned(),
                        }));
                    }
                }
                _ => {}
            }
        }
        Ok(None)
    }
}

/// The messages of a bag, file after file. After an error it ends.
pub struct Messages {
    files: std::vec::IntoIter<PathBuf>,
    current: Option<McapFile>,
    wanted: Vec<String>,
    failed: bool,
}

impl Iterator for Messages {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed {
            if self.current.is_none() {
                let path = self.files.next()?;
                match McapFile::open(&path, self.wanted.clone()) {
                    Ok(f) => self.current = Some(f),
                    Err(e) => {
                        self.failed = true;
                        return Some(Err(e));
                    }
                }
            }
            match self.current.as_mut()?.next_message() {
                Ok(Some(m)) => return Some(Ok(m)),
                Ok(None) => self.current = None,
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_names_the_storage_and_the_files_in_order() {
        let text = "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  \
                    relative_file_paths:\n    - run_0.mcap\n    - \"run_1.mcap\"\n  duration:\n    nanoseconds: 5\n";
        assert_eq!(read_metadata(text), (Some("mcap".into()), vec!["run_0.mcap".into(), "run_1.mcap".into()]));
    }
}
