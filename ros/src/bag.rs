//! Bags, read in bag order without loading them whole: a rosbag2 directory (its
//! `metadata.yaml` names the files, in order) or a single file, in MCAP storage (`.mcap`,
//! [`crate::mcap_file`]) or sqlite3 storage (`.db3`, [`crate::db3`]), or a ROS 1 bag (`.bag`,
//! [`crate::ros1_bag`]). Each message comes with its topic and its ROS type
//! (`sensor_msgs/msg/LaserScan`); the bytes are CDR, or ROS 1's serialization, as the message
//! says ([`crate::msg`] decodes both).
//!
//! A file that stops making sense (cut short, a bad chunk) ends the reading there with an error
//! naming it; the messages before it have been returned. Other storage (a compressed bag's
//! `.mcap.zstd`) is refused with the command that converts it.

use crate::db3::Db3File;
use crate::mcap_file::McapFile;
use crate::ros1_bag::Ros1BagFile;
pub use crate::stored::{BagError, BagMessage, TopicInfo};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A bag: its data files, in order.
#[derive(Clone, Debug)]
pub struct Bag {
    pub path: PathBuf,
    pub files: Vec<PathBuf>,
}

impl Bag {
    /// The bag at `path`: a directory holding `metadata.yaml`, or one `.mcap`, `.db3` or ROS 1
    /// `.bag` file (a ROS 1 bag by any name).
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
            if let Some(s) = storage.filter(|s| s != "mcap" && s != "sqlite3") {
                return Err(BagError::Storage { path: path.to_owned(), storage: s });
            }
            if names.is_empty() {
                return Err(BagError::NoFiles { path: path.to_owned() });
            }
            let files: Vec<PathBuf> = names.iter().map(|n| path.join(n)).collect();
            if let Some(f) = files.iter().find(|f| FileKind::of(f).is_none()) {
                let storage = f.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
                return Err(BagError::Storage { path: f.clone(), storage });
            }
            return Ok(Bag { path: path.to_owned(), files });
        }
        std::fs::metadata(path).map_err(io)?;
        match FileKind::of(path) {
            Some(_) => Ok(Bag { path: path.to_owned(), files: vec![path.to_owned()] }),
            None => Err(BagError::NotABag { path: path.to_owned() }),
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
            let found = match FileKind::of(file) {
                Some(FileKind::Db3) => crate::db3::topics(file)?,
                Some(FileKind::Ros1) => crate::ros1_bag::topics(file)?,
                _ => crate::mcap_file::topics(file)?,
            };
            for t in found {
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

/// The storage of one bag file, by its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FileKind {
    Mcap,
    Db3,
    Ros1,
}

impl FileKind {
    fn of(path: &Path) -> Option<FileKind> {
        match path.extension().and_then(|e| e.to_str()) {
            Some("mcap") => Some(FileKind::Mcap),
            Some("db3") => Some(FileKind::Db3),
            Some("bag") => Some(FileKind::Ros1),
            _ if crate::ros1_bag::is_ros1_bag(path) => Some(FileKind::Ros1),
            _ => None,
        }
    }
}

/// One bag file being read, whatever its storage.
enum FileReader {
    Mcap(McapFile),
    Db3(Db3File),
    Ros1(Ros1BagFile),
}

impl FileReader {
    fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
        match FileKind::of(path) {
            Some(FileKind::Db3) => Db3File::open(path, wanted).map(FileReader::Db3),
            Some(FileKind::Ros1) => Ros1BagFile::open(path, wanted).map(FileReader::Ros1),
            _ => McapFile::open(path, wanted).map(FileReader::Mcap),
        }
    }

    fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
        match self {
            FileReader::Mcap(f) => f.next_message(),
            FileReader::Db3(f) => f.next_message(),
            FileReader::Ros1(f) => f.next_message(),
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

/// The messages of a bag, file after file. After an error it ends.
pub struct Messages {
    files: std::vec::IntoIter<PathBuf>,
    current: Option<FileReader>,
    wanted: Vec<String>,
    failed: bool,
}

impl Iterator for Messages {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed {
            if self.current.is_none() {
                let path = self.files.next()?;
                match FileReader::open(&path, self.wanted.clone()) {
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
