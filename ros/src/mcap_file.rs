//! rosbag2 files in MCAP storage (`.mcap`), read from start to end without loading them
//! whole, chunks plain or compressed (zstd, lz4); their topics from the summary section, or by
//! reading through a file that has none (cut short).

use crate::stored::{BagError, BagMessage, Encoding, TopicInfo};
use mcap::sans_io::{LinearReadEvent, LinearReader, SummaryReadEvent, SummaryReader};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn mcap_error(path: &Path, e: impl std::fmt::Display) -> BagError {
    BagError::Mcap { path: path.to_owned(), cause: e.to_string() }
}

/// The topics of one MCAP file, from its summary or, without one (a file cut short, a writer
/// that wrote none), by reading it through: as far as it reads, when that finds any.
pub fn topics(path: &Path) -> Result<Vec<TopicInfo>, BagError> {
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
pub struct McapFile {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    schemas: HashMap<u16, Arc<str>>,
    /// Channel id -> topic and type.
    channels: HashMap<u16, (Arc<str>, Arc<str>)>,
    wanted: Vec<String>,
}

impl McapFile {
    pub fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
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
    pub fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
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
                            encoding: Encoding::Cdr,
                        }));
                    }
                }
                _ => {}
            }
        }
        Ok(None)
    }
}
