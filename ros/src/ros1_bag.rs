//! ROS 1 bags (format 2.0, a `.bag` file), read in file order without loading them whole: the
//! bags of ROS 1 robots and of many public datasets. Chunks are read plain, bz2 or lz4
//! compressed; the connections met on the way give each message its topic and type, whose ROS
//! 1 name (`sensor_msgs/LaserScan`) is given in ROS 2's form (`sensor_msgs/msg/LaserScan`),
//! and its bytes are ROS 1's serialization ([`Encoding::Ros1`]).
//!
//! A bag with an index (its connections and, per chunk, the connections it holds) has the
//! chunks without a wanted topic passed over unread: a laser topic beside cameras reads a
//! fraction of the file.
//!
//! A record is a `u32` header length, the header (fields of a `u32` length and `name=value`),
//! a `u32` data length and the data. Every length is checked against what the file holds and
//! read as it arrives, so a hostile length is an error, never a huge allocation. A bag cut
//! short (a recording that was killed has no index either) yields its messages up to the cut,
//! then an error naming where.

use crate::stored::{BagError, BagMessage, Encoding, TopicInfo};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The first line of a bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// Largest record header read: the fields of a record are a few short values.
const MAX_HEADER: u32 = 1 << 20;

/// Largest chunk decompressed ([`crate::stored::MAX_RECORD_BYTES`]).
const MAX_CHUNK: u64 = crate::stored::MAX_RECORD_BYTES as u64;

/// The record kinds (the `op` field).
const OP_MESSAGE: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

/// Whether the file at `path` opens as a ROS 1 bag of any version (`#ROSBAG V`).
pub fn is_ros1_bag(path: &Path) -> bool {
    let mut head = [0u8; 9];
    File::open(path).and_then(|mut f| f.read_exact(&mut head)).is_ok() && &head == b"#ROSBAG V"
}

/// One record: its header's fields and its data.
struct Record {
    fields: Vec<(String, Vec<u8>)>,
    data: Vec<u8>,
}

impl Record {
    fn field(&self, name: &str) -> Option<&[u8]> {
        self.fields.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_slice())
    }

    fn op(&self) -> Result<u8, String> {
        match self.field("op") {
            Some(&[op]) => Ok(op),
            _ => Err("a record without its one-byte op".into()),
        }
    }

    fn u32_field(&self, name: &str) -> Result<u32, String> {
        match self.field(name) {
            Some(b) if b.len() == 4 => Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            _ => Err(format!("a record without its 4-byte `{name}`")),
        }
    }

    fn u64_field(&self, name: &str) -> Result<u64, String> {
        match self.field(name) {
            Some(b) if b.len() == 8 => Ok(u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])),
            _ => Err(format!("a record without its 8-byte `{name}`")),
        }
    }

    fn text_field(&self, name: &str) -> Result<String, String> {
        let b = self.field(name).ok_or_else(|| format!("a record without its `{name}`"))?;
        String::from_utf8(b.to_vec()).map_err(|_| format!("a `{name}` that is not UTF-8"))
    }
}

/// The `name=value` fields of a record header (or of a connection record's data).
fn parse_fields(mut b: &[u8]) -> Result<Vec<(String, Vec<u8>)>, String> {
    let mut fields = Vec::new();
    while !b.is_empty() {
        let (len, rest) = split_u32(b).ok_or("a header field cut short")?;
        let field = rest.get(..len as usize).ok_or("a header field longer than its header")?;
        let eq = field.iter().position(|&c| c == b'=').ok_or("a header field without `=`")?;
        let name = std::str::from_utf8(&field[..eq]).map_err(|_| "a header field name that is not UTF-8")?;
        fields.push((name.to_owned(), field[eq + 1..].to_vec()));
        b = &rest[len as usize..];
    }
    Ok(fields)
}

fn split_u32(b: &[u8]) -> Option<(u32, &[u8])> {
    let (head, rest) = b.split_at_checked(4)?;
    Some((u32::from_le_bytes([head[0], head[1], head[2], head[3]]), rest))
}

/// Reads exactly `len` bytes as they arrive (a hostile length cannot allocate more than the
/// source holds); `None` when the source ends first.
fn read_exactly(r: &mut impl Read, len: u64) -> std::io::Result<Option<Vec<u8>>> {
    let mut out = Vec::new();
    r.take(len).read_to_end(&mut out)?;
    Ok((out.len() as u64 == len).then_some(out))
}

/// The next record of `r`: `Ok(None)` at a clean end (no byte left), an error when the
/// record is cut short or malformed.
fn next_record(r: &mut impl Read) -> Result<Option<Record>, String> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < 4 {
        match r.read(&mut len[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => return Err("a record cut short in its header length".into()),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.to_string()),
        }
    }
    let header_len = u32::from_le_bytes(len);
    if header_len > MAX_HEADER {
        return Err(format!("a record header of {header_len} bytes (at most {MAX_HEADER} are read)"));
    }
    let header =
        read_exactly(r, u64::from(header_len)).map_err(|e| e.to_string())?.ok_or("a record cut short in its header")?;
    let fields = parse_fields(&header)?;
    let data_len = read_exactly(r, 4).map_err(|e| e.to_string())?.ok_or("a record cut short before its data")?;
    let data_len = u32::from_le_bytes([data_len[0], data_len[1], data_len[2], data_len[3]]);
    let data =
        read_exactly(r, u64::from(data_len)).map_err(|e| e.to_string())?.ok_or("a record cut short in its data")?;
    Ok(Some(Record { fields, data }))
}

/// A ROS 1 type name in ROS 2's form: `pkg/Type` becomes `pkg/msg/Type`; ROS 1's `tf/tfMessage`
/// is `tf2_msgs/msg/TFMessage`, which it is field for field.
pub fn ros2_type_name(ros1: &str) -> String {
    if ros1 == "tf/tfMessage" {
        return "tf2_msgs/msg/TFMessage".into();
    }
    match ros1.split_once('/') {
        Some((pkg, name)) if !name.contains('/') => format!("{pkg}/msg/{name}"),
        _ => ros1.to_owned(),
    }
}

/// A connection: its topic and type (ROS 2's name).
#[derive(Clone)]
struct Connection {
    topic: Arc<str>,
    ros_type: Arc<str>,
}

/// A connection record's id and connection.
fn connection(record: &Record) -> Result<(u32, Connection), String> {
    let id = record.u32_field("conn")?;
    let topic = record.text_field("topic")?;
    let data = Record { fields: parse_fields(&record.data)?, data: Vec::new() };
    let ros_type = ros2_type_name(&data.text_field("type")?);
    Ok((id, Connection { topic: topic.into(), ros_type: ros_type.into() }))
}

/// A chunk's records, decompressed.
fn chunk_records(record: &Record) -> Result<Vec<u8>, String> {
    let compression = record.text_field("compression")?;
    let size = u64::from(record.u32_field("size")?);
    if size > MAX_CHUNK {
        return Err(format!("a chunk of {size} bytes (at most {MAX_CHUNK} are read)"));
    }
    let data = record.data.as_slice();
    let out = match compression.as_str() {
        "none" => Some(data.to_vec()),
        "bz2" => read_exactly(&mut bzip2::read::BzDecoder::new(data), size).map_err(|e| format!("bz2: {e}"))?,
        "lz4" => read_exactly(&mut lz4_flex::frame::FrameDecoder::new(data), size).map_err(|e| format!("lz4: {e}"))?,
        other => return Err(format!("a chunk compressed as {other:?} (none, bz2 and lz4 are read)")),
    };
    match out {
        Some(out) if out.len() as u64 == size => Ok(out),
        _ => Err(format!("a {compression} chunk holding less than the {size} bytes it declares")),
    }
}

/// The bag's header record, after the magic line: where its index starts (0 when it has none,
/// as a bag whose recording was killed).
fn read_bag_header(r: &mut impl Read, path: &Path) -> Result<u64, BagError> {
    let bad = |cause: String| BagError::Ros1 { path: path.to_owned(), cause };
    let mut magic = [0u8; MAGIC.len()];
    r.read_exact(&mut magic).map_err(|_| bad("shorter than the format line".into()))?;
    if magic != MAGIC {
        let line = String::from_utf8_lossy(&magic);
        return Err(bad(format!("{:?} is not format 2.0 (`rosbag fix` brings an old bag to it)", line.trim_end())));
    }
    let record = next_record(r).map_err(&bad)?.ok_or_else(|| bad("no bag header record".into()))?;
    if record.op().map_err(&bad)? != OP_BAG_HEADER {
        return Err(bad("the first record is not the bag header".into()));
    }
    record.u64_field("index_pos").map_err(bad)
}

/// A bag's index: its connections, and each chunk's place with the connections it holds.
struct Index {
    connections: BTreeMap<u32, Connection>,
    chunks: Vec<(u64, Vec<(u32, u32)>)>,
}

/// Reads the index at `index_pos` (the connection and chunk-info records after the chunks).
fn read_index(reader: &mut BufReader<File>, index_pos: u64) -> Result<Index, String> {
    reader.seek(SeekFrom::Start(index_pos)).map_err(|e| e.to_string())?;
    let mut index = Index { connections: BTreeMap::new(), chunks: Vec::new() };
    while let Some(record) = next_record(reader).map_err(|e| format!("in the index: {e}"))? {
        match record.op()? {
            OP_CONNECTION => {
                let (id, c) = connection(&record)?;
                index.connections.insert(id, c);
            }
            OP_CHUNK_INFO => {
                // (connection, messages in the chunk) pairs
                let held = record
                    .data
                    .chunks_exact(8)
                    .map(|p| {
                        (u32::from_le_bytes([p[0], p[1], p[2], p[3]]), u32::from_le_bytes([p[4], p[5], p[6], p[7]]))
                    })
                    .collect();
                index.chunks.push((record.u64_field("chunk_pos")?, held));
            }
            _ => {}
        }
    }
    Ok(index)
}

/// One ROS 1 bag file being read in file order.
pub struct Ros1BagFile {
    path: PathBuf,
    reader: BufReader<File>,
    wanted: Vec<String>,
    connections: HashMap<u32, Connection>,
    /// The chunk being read and where in it.
    chunk: Vec<u8>,
    at: usize,
    /// Bytes of the file read so far: where the next record starts.
    offset: u64,
    length: u64,
    /// Where the chunks holding no wanted topic start (from the index): passed over unread.
    unwanted: HashSet<u64>,
}

impl Ros1BagFile {
    /// Opens `path` to read the messages on `wanted` topics (every topic when empty).
    pub fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
        let io = |cause| BagError::Io { path: path.to_owned(), cause };
        let file = File::open(path).map_err(io)?;
        let length = file.metadata().map_err(io)?.len();
        let mut reader = BufReader::new(file);
        let index_pos = read_bag_header(&mut reader, path)?;
        let offset = reader.stream_position().map_err(io)?;
        let mut connections = HashMap::new();
        let mut unwanted = HashSet::new();
        if !wanted.is_empty() && index_pos >= offset && index_pos < length {
            // a broken index only costs the passing over: the chunks are read as they come
            if let Ok(index) = read_index(&mut reader, index_pos) {
                let ids: HashSet<u32> = index
                    .connections
                    .iter()
                    .filter(|(_, c)| wanted.iter().any(|w| **w == *c.topic))
                    .map(|(&id, _)| id)
                    .collect();
                unwanted = index
                    .chunks
                    .iter()
                    .filter(|(_, held)| held.iter().all(|(id, _)| !ids.contains(id)))
                    .map(|(pos, _)| *pos)
                    .collect();
                connections.extend(index.connections);
            }
            reader.seek(SeekFrom::Start(offset)).map_err(io)?;
        }
        Ok(Ros1BagFile {
            path: path.to_owned(),
            reader,
            wanted,
            connections,
            chunk: Vec::new(),
            at: 0,
            offset,
            length,
            unwanted,
        })
    }

    fn bad(&self, cause: String) -> BagError {
        BagError::Ros1 { path: self.path.clone(), cause: format!("{cause}, at byte {}", self.offset) }
    }

    /// The next message on a wanted topic, `None` at the end of the file.
    pub fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
        loop {
            // the chunk's records first, then the file's
            let record = if self.at < self.chunk.len() {
                let mut rest = &self.chunk[self.at..];
                let before = rest.len();
                let record = next_record(&mut rest).map_err(|e| self.bad(format!("in a chunk: {e}")))?;
                self.at += before - rest.len();
                record
            } else {
                self.chunk.clear();
                self.at = 0;
                if self.unwanted.contains(&self.offset) {
                    self.pass_over()?;
                    continue;
                }
                let record = next_record(&mut self.reader).map_err(|e| self.bad(e))?;
                self.offset =
                    self.reader.stream_position().map_err(|cause| BagError::Io { path: self.path.clone(), cause })?;
                match record {
                    None => return Ok(None),
                    Some(r) if r.op().map_err(|e| self.bad(e))? == OP_CHUNK => {
                        self.chunk = chunk_records(&r).map_err(|e| self.bad(e))?;
                        continue;
                    }
                    Some(r) => Some(r),
                }
            };
            let Some(record) = record else { continue };
            match record.op().map_err(|e| self.bad(e))? {
                OP_CONNECTION => {
                    let (id, c) = connection(&record).map_err(|e| self.bad(e))?;
                    self.connections.insert(id, c);
                }
                OP_MESSAGE => {
                    let id = record.u32_field("conn").map_err(|e| self.bad(e))?;
                    let time = record.u64_field("time").map_err(|e| self.bad(e))?;
                    let c = self
                        .connections
                        .get(&id)
                        .ok_or_else(|| self.bad(format!("a message on connection {id}, which no record defined")))?;
                    if self.wanted.is_empty() || self.wanted.iter().any(|w| **w == *c.topic) {
                        // time: seconds then nanoseconds, each a u32
                        let (sec, nsec) = (time & 0xffff_ffff, time >> 32);
                        return Ok(Some(BagMessage {
                            topic: Arc::clone(&c.topic),
                            ros_type: Arc::clone(&c.ros_type),
                            log_time: sec * 1_000_000_000 + nsec,
                            data: record.data,
                            encoding: Encoding::Ros1,
                        }));
                    }
                }
                // the bag header again, index data and chunk info: nothing to read
                _ => {}
            }
        }
    }
}

impl Ros1BagFile {
    /// Passes over the record at `offset` (a chunk holding no wanted topic): reads its header
    /// and length, not its data.
    fn pass_over(&mut self) -> Result<(), BagError> {
        let mut head = [0u8; 4];
        self.reader.read_exact(&mut head).map_err(|e| self.bad(format!("a chunk cut short: {e}")))?;
        let header_len = u32::from_le_bytes(head);
        if header_len > MAX_HEADER {
            return Err(self.bad(format!("a record header of {header_len} bytes (at most {MAX_HEADER} are read)")));
        }
        self.reader.seek_relative(i64::from(header_len)).map_err(|e| self.bad(format!("a chunk cut short: {e}")))?;
        self.reader.read_exact(&mut head).map_err(|e| self.bad(format!("a chunk cut short: {e}")))?;
        let data_len = u64::from(u32::from_le_bytes(head));
        let end = self.offset + 8 + u64::from(header_len) + data_len;
        if end > self.length {
            return Err(self.bad("a chunk cut short in its data".into()));
        }
        self.reader.seek_relative(data_len as i64).map_err(|e| self.bad(format!("a chunk cut short: {e}")))?;
        self.offset = end;
        Ok(())
    }
}

/// The topics of the bag at `path` with their types and message counts: from its index (the
/// connection and chunk-info records at `index_pos`), or, in a bag without one, by reading it
/// through.
pub fn topics(path: &Path) -> Result<Vec<TopicInfo>, BagError> {
    let io = |cause| BagError::Io { path: path.to_owned(), cause };
    let bad = |cause: String| BagError::Ros1 { path: path.to_owned(), cause };
    let mut reader = BufReader::new(File::open(path).map_err(io)?);
    let index = read_bag_header(&mut reader, path)?;
    let length = reader.get_ref().metadata().map_err(io)?.len();
    let mut connections: BTreeMap<u32, Connection> = BTreeMap::new();
    let mut counts: HashMap<u32, u64> = HashMap::new();
    if index > 0 && index < length {
        let found = read_index(&mut reader, index).map_err(bad)?;
        for (id, n) in found.chunks.iter().flat_map(|(_, held)| held) {
            *counts.entry(*id).or_default() += u64::from(*n);
        }
        connections = found.connections;
    } else {
        let mut file = Ros1BagFile::open(path, Vec::new())?;
        while let Some(m) = file.next_message()? {
            let id = file.connections.iter().find(|(_, c)| Arc::ptr_eq(&c.topic, &m.topic)).map(|(&id, _)| id);
            if let Some(id) = id {
                *counts.entry(id).or_default() += 1;
            }
        }
        connections.extend(file.connections);
    }
    // several connections (publishers) may share a topic
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    for (id, c) in connections {
        let t = topics.entry(c.topic.to_string()).or_insert(TopicInfo {
            name: c.topic.to_string(),
            ros_type: c.ros_type.to_string(),
            messages: Some(0),
        });
        t.messages = t.messages.map(|n| n + counts.get(&id).copied().unwrap_or(0));
    }
    Ok(topics.into_values().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Decode, LaserScan, Odometry};
    use proptest::prelude::*;

    /// A record of `fields` (name, value) and `data`.
    fn record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
        let mut header = Vec::new();
        for (name, value) in fields {
            header.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
            header.extend(name.as_bytes());
            header.push(b'=');
            header.extend(*value);
        }
        let mut out = (header.len() as u32).to_le_bytes().to_vec();
        out.extend(header);
        out.extend((data.len() as u32).to_le_bytes());
        out.extend(data);
        out
    }

    fn connection_record(id: u32, topic: &str, ros_type: &str) -> Vec<u8> {
        let mut data = Vec::new();
        for (name, value) in [("topic", topic), ("type", ros_type), ("md5sum", "*"), ("message_definition", "")] {
            data.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
            data.extend(format!("{name}={value}").as_bytes());
        }
        record(&[("op", &[OP_CONNECTION]), ("conn", &id.to_le_bytes()), ("topic", topic.as_bytes())], &data)
    }

    fn message_record(id: u32, sec: u32, nsec: u32, data: &[u8]) -> Vec<u8> {
        let time = (u64::from(nsec) << 32) | u64::from(sec);
        record(&[("op", &[OP_MESSAGE]), ("conn", &id.to_le_bytes()), ("time", &time.to_le_bytes())], data)
    }

    /// A ROS 1 LaserScan of `ranges`, serialized as ROS 1 does (a header with `seq`).
    fn ros1_scan(seq: u32, sec: u32, ranges: &[f32]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend(seq.to_le_bytes());
        b.extend(sec.to_le_bytes());
        b.extend(7u32.to_le_bytes());
        b.extend(5u32.to_le_bytes());
        b.extend(b"laser");
        for v in [-1.5f32, 1.5, 0.01, 0.0, 0.1, 0.02, 30.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend((ranges.len() as u32).to_le_bytes());
        for r in ranges {
            b.extend(r.to_le_bytes());
        }
        b.extend(0u32.to_le_bytes());
        b
    }

    /// A chunk: its compression, its records and the (connection, messages) pairs it holds.
    type Chunk = (&'static str, Vec<u8>, Vec<(u32, u32)>);

    /// A bag of `chunks` (each compressed as named), with an index after them when `indexed`:
    /// `connections`, then a chunk-info record per chunk.
    fn bag(chunks: &[Chunk], connections: &[Vec<u8>], indexed: bool) -> Vec<u8> {
        let mut body = Vec::new();
        let mut infos = Vec::new();
        for (compression, records, held) in chunks {
            infos.push(chunk_info((MAGIC.len() + 4096 + body.len()) as u64, held));
            let data = match *compression {
                "none" => records.clone(),
                "bz2" => {
                    let mut out = Vec::new();
                    std::io::copy(
                        &mut bzip2::read::BzEncoder::new(records.as_slice(), bzip2::Compression::default()),
                        &mut out,
                    )
                    .unwrap();
                    out
                }
                "lz4" => {
                    let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
                    std::io::Write::write_all(&mut e, records).unwrap();
                    e.finish().unwrap()
                }
                other => other.as_bytes().to_vec(),
            };
            let size = (records.len() as u32).to_le_bytes();
            body.extend(record(
                &[("op", &[OP_CHUNK]), ("compression", compression.as_bytes()), ("size", &size)],
                &data,
            ));
            // an index data record after each chunk, as rosbag writes (skipped)
            body.extend(record(&[("op", &[0x04]), ("ver", &1u32.to_le_bytes())], &[]));
        }
        // the bag header record, padded to 4096 bytes as rosbag pads it
        let index_pos = if indexed { (MAGIC.len() + 4096 + body.len()) as u64 } else { 0 };
        let fields: [(&str, &[u8]); 4] = [
            ("op", &[OP_BAG_HEADER]),
            ("index_pos", &index_pos.to_le_bytes()),
            ("conn_count", &1u32.to_le_bytes()),
            ("chunk_count", &(chunks.len() as u32).to_le_bytes()),
        ];
        let head = record(&fields, &vec![b' '; 4096 - record(&fields, &[]).len()]);
        assert_eq!(head.len(), 4096);
        let mut out = MAGIC.to_vec();
        out.extend(head);
        out.extend(body);
        if indexed {
            for r in connections.iter().chain(&infos) {
                out.extend(r);
            }
        }
        out
    }

    fn chunk_info(pos: u64, counts: &[(u32, u32)]) -> Vec<u8> {
        let data: Vec<u8> = counts.iter().flat_map(|&(c, n)| [c.to_le_bytes(), n.to_le_bytes()].concat()).collect();
        let count = (counts.len() as u32).to_le_bytes();
        record(&[("op", &[OP_CHUNK_INFO]), ("chunk_pos", &pos.to_le_bytes()), ("count", &count)], &data)
    }

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    /// Scans on /scan (connection 0) and an odometry on /odom (connection 1), over three
    /// chunks compressed each way.
    fn three_chunks() -> (Vec<Chunk>, Vec<Vec<u8>>) {
        // an Odometry in ROS 1: seq, stamp, frame_id, child_frame_id, then the pose (x = 2.5,
        // facing +y), its covariance, the twist and its covariance
        let mut ros1_odom = Vec::new();
        for v in [0u32, 9, 0, 4] {
            ros1_odom.extend(v.to_le_bytes());
        }
        ros1_odom.extend(b"odom");
        ros1_odom.extend(9u32.to_le_bytes());
        ros1_odom.extend(b"base_link");
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for v in [2.5, 0.0, 0.0, 0.0, 0.0, half, half].into_iter().chain([0.0; 36 + 6 + 36]) {
            ros1_odom.extend(f64::to_le_bytes(v));
        }
        let first = [
            connection_record(0, "/scan", "sensor_msgs/LaserScan"),
            message_record(0, 100, 5, &ros1_scan(1, 100, &[1.0, 2.0])),
        ]
        .concat();
        let second =
            [connection_record(1, "/odom", "nav_msgs/Odometry"), message_record(1, 101, 0, &ros1_odom)].concat();
        let third = message_record(0, 102, 0, &ros1_scan(2, 102, &[3.0]));
        let connections = vec![
            connection_record(0, "/scan", "sensor_msgs/LaserScan"),
            connection_record(1, "/odom", "nav_msgs/Odometry"),
        ];
        (vec![("none", first, vec![(0, 1)]), ("bz2", second, vec![(1, 1)]), ("lz4", third, vec![(0, 1)])], connections)
    }

    #[test]
    fn messages_come_in_file_order_through_every_compression_decoded_as_ros1() {
        let dir = tempfile::tempdir().unwrap();
        let (chunks, index) = three_chunks();
        for indexed in [true, false] {
            let path = write(dir.path(), "a.bag", &bag(&chunks, &index, indexed));
            let mut file = Ros1BagFile::open(&path, Vec::new()).unwrap();
            let mut got = Vec::new();
            while let Some(m) = file.next_message().unwrap() {
                got.push(m);
            }
            let order: Vec<&str> = got.iter().map(|m| &*m.topic).collect();
            assert_eq!(order, ["/scan", "/odom", "/scan"]);
            assert_eq!(&*got[0].ros_type, LaserScan::TYPE);
            assert_eq!(&*got[1].ros_type, Odometry::TYPE);
            assert_eq!(got[0].log_time, 100_000_000_005);
            assert!(got.iter().all(|m| m.encoding == Encoding::Ros1));
            let scan = LaserScan::decode_as(Encoding::Ros1, &got[0].data).unwrap();
            assert_eq!((scan.header.stamp.sec, scan.header.stamp.nanosec), (100, 7));
            assert_eq!((scan.header.frame_id.as_str(), scan.ranges.as_slice()), ("laser", &[1.0f32, 2.0][..]));
            assert_eq!(scan.range_max, 30.0);
            let odom = Odometry::decode_as(Encoding::Ros1, &got[1].data).unwrap();
            assert_eq!((odom.header.stamp.sec, odom.header.frame_id.as_str()), (9, "odom"));
            assert_eq!(odom.child_frame_id, "base_link");
            let (x, y, yaw) = odom.pose.pose.planar();
            assert!((x - 2.5).abs() < 1e-12 && y == 0.0 && (yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
            // only the wanted topic
            let mut file = Ros1BagFile::open(&path, vec!["/odom".into()]).unwrap();
            assert_eq!(&*file.next_message().unwrap().unwrap().topic, "/odom");
            assert!(file.next_message().unwrap().is_none());
            // with an index, the chunks without it are passed over unread: a chunk of /scan
            // that would not decompress is not even looked at
            let mut spoilt = chunks.clone();
            spoilt[2].0 = "zstd";
            let path = write(dir.path(), "s.bag", &bag(&spoilt, &index, indexed));
            let mut file = Ros1BagFile::open(&path, vec!["/odom".into()]).unwrap();
            assert_eq!(&*file.next_message().unwrap().unwrap().topic, "/odom");
            assert_eq!(file.next_message().is_err(), !indexed);
            // the topics, from the index or read through
            let t = topics(&dir.path().join("a.bag")).unwrap();
            let listed: Vec<(&str, &str, Option<u64>)> =
                t.iter().map(|t| (t.name.as_str(), t.ros_type.as_str(), t.messages)).collect();
            assert_eq!(listed, [("/odom", Odometry::TYPE, Some(1)), ("/scan", LaserScan::TYPE, Some(2))], "{indexed}");
        }
    }

    #[test]
    fn a_bag_cut_short_gives_its_messages_before_the_cut_then_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let (chunks, index) = three_chunks();
        let whole = bag(&chunks, &index, false);
        // cut inside the last chunk
        let path = write(dir.path(), "cut.bag", &whole[..whole.len() - 30]);
        let mut file = Ros1BagFile::open(&path, Vec::new()).unwrap();
        assert!(file.next_message().unwrap().is_some());
        assert!(file.next_message().unwrap().is_some());
        let e = file.next_message().unwrap_err().to_string();
        assert!(e.contains("cut.bag: not a readable ROS 1 bag: a record cut short") && e.contains("at byte"), "{e}");
    }

    #[test]
    fn bad_bags_are_refused_in_words() {
        let dir = tempfile::tempdir().unwrap();
        let (chunks, index) = three_chunks();
        let good = bag(&chunks, &index, true);
        let old = write(dir.path(), "old.bag", b"#ROSBAG V1.2\nrest");
        let e = Ros1BagFile::open(&old, Vec::new()).err().unwrap().to_string();
        assert!(e.contains("\"#ROSBAG V1.2\" is not format 2.0") && e.contains("rosbag fix"), "{e}");
        // a chunk of an unknown compression
        let zstd = write(dir.path(), "z.bag", &bag(&[("zstd", chunks[0].1.clone(), vec![])], &[], false));
        let mut file = Ros1BagFile::open(&zstd, Vec::new()).unwrap();
        let e = file.next_message().unwrap_err().to_string();
        assert!(e.contains("compressed as \"zstd\""), "{e}");
        // a message before any connection names its topic
        let orphan = write(dir.path(), "o.bag", &bag(&[("none", message_record(4, 1, 0, b""), vec![])], &[], false));
        let e = Ros1BagFile::open(&orphan, Vec::new()).unwrap().next_message().unwrap_err().to_string();
        assert!(e.contains("connection 4, which no record defined"), "{e}");
        // a huge record header length
        let mut huge = good[..MAGIC.len() + 4096].to_vec();
        huge.extend(u32::MAX.to_le_bytes());
        let huge = write(dir.path(), "h.bag", &huge);
        let e = Ros1BagFile::open(&huge, Vec::new()).unwrap().next_message().unwrap_err().to_string();
        assert!(e.contains("at most"), "{e}");
        // a ROS 1 bag by another name is still one
        let other = write(dir.path(), "recording.dat", &good);
        assert!(is_ros1_bag(&other) && !is_ros1_bag(&zstd.with_extension("none")));
    }

    #[test]
    fn ros1_type_names_take_ros2_s_form() {
        assert_eq!(ros2_type_name("sensor_msgs/LaserScan"), "sensor_msgs/msg/LaserScan");
        assert_eq!(ros2_type_name("tf/tfMessage"), "tf2_msgs/msg/TFMessage");
        assert_eq!(ros2_type_name("odd"), "odd");
    }

    proptest! {
        /// Bytes after a bag's header never panic the reader, nor allocate what they claim.
        #[test]
        fn arbitrary_records_are_an_error_or_messages(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let dir = tempfile::tempdir().unwrap();
            let (chunks, index) = three_chunks();
            let mut b = bag(&chunks[..1], &index, false);
            b.truncate(MAGIC.len() + 4096);
            b.extend(&bytes);
            let path = write(dir.path(), "f.bag", &b);
            if let Ok(mut file) = Ros1BagFile::open(&path, Vec::new()) {
                for _ in 0..64 {
                    match file.next_message() {
                        Ok(Some(_)) => {}
                        _ => break,
                    }
                }
            }
            let _ = topics(&path);
        }

        /// A whole bag (chunks plain, bz2 and lz4) with a few bytes changed, a length, a field
        /// or a compressed byte, is read or refused: never a panic, a hang, or an allocation of
        /// what a damaged length claims.
        #[test]
        fn damaged_bags_are_an_error_or_messages(
            indexed in any::<bool>(),
            edits in proptest::collection::vec(
                (
                    any::<proptest::sample::Index>(),
                    prop_oneof![
                        any::<u8>().prop_map(|b| vec![b]),
                        any::<u32>().prop_map(|v| v.to_le_bytes().to_vec()),
                        Just(u32::MAX.to_le_bytes().to_vec()),
                        Just(0u32.to_le_bytes().to_vec()),
                    ],
                ),
                1..6,
            ),
        ) {
            let dir = tempfile::tempdir().unwrap();
            let (chunks, index) = three_chunks();
            let mut b = bag(&chunks, &index, indexed);
            for (at, bytes) in edits {
                let at = at.index(b.len());
                for (k, v) in bytes.into_iter().enumerate() {
                    if let Some(x) = b.get_mut(at + k) {
                        *x = v;
                    }
                }
            }
            let path = write(dir.path(), "f.bag", &b);
            if let Ok(mut file) = Ros1BagFile::open(&path, Vec::new()) {
                for _ in 0..64 {
                    match file.next_message() {
                        Ok(Some(m)) => {
                            let _ = LaserScan::decode_as(Encoding::Ros1, &m.data);
                            let _ = Odometry::decode_as(Encoding::Ros1, &m.data);
                        }
                        _ => break,
                    }
                }
            }
            let _ = topics(&path);
        }
    }
}
