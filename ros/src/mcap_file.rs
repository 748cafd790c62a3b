//! rosbag2 files in MCAP storage (`.mcap`), read from start to end without loading them
//! whole, chunks plain or compressed (zstd, lz4); their topics from the summary section, or by
//! reading through a file that has none (cut short). A damaged or hostile file is an error at
//! the damage, after the messages before it: no record or chunk is taken in beyond
//! [`MAX_RECORD_BYTES`], and no chunk is decompressed past the size it declares.

use crate::stored::{BagError, BagMessage, Encoding, TopicInfo, MAX_RECORD_BYTES};
use mcap::sans_io::{SummaryReadEvent, SummaryReader};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
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
    let options =
        mcap::sans_io::SummaryReaderOptions::default().with_file_size(size).with_record_length_limit(MAX_RECORD_BYTES);
    let mut reader = SummaryReader::new_with_options(options);
    // where the file is read: a request past its end is a damaged summary, not a buffer of
    // the size a damaged length claims
    let mut at = 0u64;
    while let Some(event) = reader.next_event() {
        match event {
            Ok(SummaryReadEvent::ReadRequest(need)) => {
                if at.saturating_add(need as u64) > size {
                    return Ok(None);
                }
                let n = file.read(reader.insert(need)).map_err(io)?;
                at += n as u64;
                reader.notify_read(n);
            }
            Ok(SummaryReadEvent::SeekRequest(to)) => {
                at = file.seek(to).map_err(io)?;
                reader.notify_seeked(at);
            }
            Err(_) => return Ok(None),
        }
    }
    Ok(reader.finish())
}

/// One MCAP file read from start to end.
///
/// The records are framed here (an opcode, a length, the body) and each chunk is decompressed
/// here, in a stream capped at the size it declares, then checked for exactly that size and
/// against its CRC; the `mcap` crate parses the records' bodies. Its own streaming reader spun
/// for ever on a chunk that declares more bytes than its compressed data holds (zstd or LZ4:
/// one damaged length field; fixed in mcap 0.26, whose summary reader `file_summary` uses),
/// and framing here keeps what is taken in within [`MAX_RECORD_BYTES`]. A chunk the file ends
/// inside (a recording killed) gives the whole records it holds, then the error.
pub struct McapFile {
    path: PathBuf,
    file: BufReader<File>,
    /// The file's bytes not yet read.
    left: u64,
    started: bool,
    /// Nothing more is read: the footer was, or an error.
    done: bool,
    /// The records of the chunk being read, and how far into them.
    chunk: Vec<u8>,
    chunk_at: usize,
    /// Why the file cannot be read past the chunk being read (it was cut inside it).
    after_chunk: Option<String>,
    topics: Topics,
}

/// What the records read so far say about the topics.
struct Topics {
    schemas: HashMap<u16, Arc<str>>,
    /// Channel id -> topic and type.
    channels: HashMap<u16, (Arc<str>, Arc<str>)>,
    wanted: Vec<String>,
}

impl Topics {
    /// Takes in one record (its opcode and body); a wanted message is returned.
    fn take(&mut self, opcode: u8, body: &[u8]) -> Result<Option<BagMessage>, String> {
        match mcap::parse_record(opcode, body).map_err(|e| e.to_string())? {
            mcap::records::Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name.into());
            }
            mcap::records::Record::Channel(c) => {
                let ros_type = self.schemas.get(&c.schema_id).cloned().unwrap_or_else(|| "".into());
                self.channels.insert(c.id, (c.topic.into(), ros_type));
            }
            mcap::records::Record::Message { header, data } => {
                let Some((topic, ros_type)) = self.channels.get(&header.channel_id) else {
                    return Err(format!("a message on channel {} before that channel's record", header.channel_id));
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
        Ok(None)
    }
}

/// A chunk record's body: how its records were compressed, the size and CRC they declare, and
/// the compressed bytes (all of them, or, with `cut`, as many as the body holds).
struct Chunk<'a> {
    compression: &'a str,
    size: usize,
    crc: u32,
    data: &'a [u8],
}

impl<'a> Chunk<'a> {
    fn parse(body: &'a [u8], cut: bool) -> Result<Self, String> {
        let short = || "a chunk record shorter than its header".to_string();
        let u64_at = |at: usize| -> Result<u64, String> {
            Ok(u64::from_le_bytes(body.get(at..at + 8).and_then(|b| b.try_into().ok()).ok_or_else(short)?))
        };
        // message start and end times, then the records' size and CRC
        let size = u64_at(16)?;
        let crc = u32::from_le_bytes(body.get(24..28).and_then(|b| b.try_into().ok()).ok_or_else(short)?);
        let name_len = u32::from_le_bytes(body.get(28..32).and_then(|b| b.try_into().ok()).ok_or_else(short)?);
        let name_end = 32usize.checked_add(name_len as usize).ok_or_else(short)?;
        let compression = std::str::from_utf8(body.get(32..name_end).ok_or_else(short)?)
            .map_err(|_| "a chunk's compression that is not text".to_string())?;
        let compressed = u64_at(name_end)?;
        let data = body.get(name_end + 8..).ok_or_else(short)?;
        let data = match usize::try_from(compressed).ok().and_then(|n| data.get(..n)) {
            Some(d) => d,
            None if cut => data,
            None => return Err(format!("a chunk declaring {compressed} compressed bytes, holding {}", data.len())),
        };
        let limit = MAX_RECORD_BYTES;
        let Some(size) = usize::try_from(size).ok().filter(|&n| n <= limit) else {
            return Err(format!("a chunk of {size} bytes (at most {limit} are read)"));
        };
        Ok(Chunk { compression, size, crc, data })
    }

    /// The compressed bytes decompressed, up to the size declared: as many as came before an
    /// error, and the error. The size bounds the output, and the decoders stop there: padding
    /// after the compressed records is never read.
    fn decompressed(&self) -> (Vec<u8>, Result<(), String>) {
        let mut out = Vec::new();
        let size = self.size as u64;
        let done = match self.compression {
            "" => self.data.take(size).read_to_end(&mut out),
            "zstd" => match zstd::stream::read::Decoder::with_buffer(self.data) {
                Ok(d) => d.take(size).read_to_end(&mut out),
                Err(e) => Err(e),
            },
            "lz4" => lz4_flex::frame::FrameDecoder::new(self.data).take(size).read_to_end(&mut out),
            other => return (out, Err(format!("a chunk compressed as {other:?} (zstd and lz4 are read)"))),
        };
        (out, done.map(|_| ()).map_err(|e| format!("{}: {e}", self.compression)))
    }

    /// The records, decompressed: exactly the size declared, matching the CRC when there is one.
    fn records(&self) -> Result<Vec<u8>, String> {
        let (out, done) = self.decompressed();
        done?;
        if out.len() != self.size {
            return Err(format!(
                "a {:?} chunk holding {} bytes where it declares {}",
                self.compression,
                out.len(),
                self.size
            ));
        }
        if self.crc != 0 && crc32fast::hash(&out) != self.crc {
            return Err("a chunk whose CRC does not match its records".into());
        }
        Ok(out)
    }

    /// As many whole records as the compressed bytes of a chunk cut short give.
    fn records_before_the_cut(&self) -> Vec<u8> {
        let (mut out, _) = self.decompressed();
        let mut whole = 0;
        // stops short of a record the cut split
        while let Ok(Some(_)) = next_chunk_record(&out, &mut whole) {}
        out.truncate(whole);
        out
    }
}

/// The next record of a chunk's `records` from `*at` on (opcode, body), moving `*at` past it;
/// `None` at their end.
fn next_chunk_record<'a>(records: &'a [u8], at: &mut usize) -> Result<Option<(u8, &'a [u8])>, String> {
    let rest = records.get(*at..).unwrap_or_default();
    if rest.is_empty() {
        return Ok(None);
    }
    let cut = || "a chunk's record cut short".to_string();
    let (&opcode, rest) = rest.split_first().ok_or_else(cut)?;
    let len: [u8; 8] = rest.get(..8).and_then(|b| b.try_into().ok()).ok_or_else(cut)?;
    let len = usize::try_from(u64::from_le_bytes(len)).map_err(|_| cut())?;
    let body = rest.get(8..).and_then(|b| b.get(..len)).ok_or_else(cut)?;
    *at += 9 + len;
    Ok(Some((opcode, body)))
}

impl McapFile {
    pub fn open(path: &Path, wanted: Vec<String>) -> Result<Self, BagError> {
        let io = |cause| BagError::Io { path: path.to_owned(), cause };
        let file = File::open(path).map_err(io)?;
        let left = file.metadata().map_err(io)?.len();
        Ok(McapFile {
            path: path.to_owned(),
            file: BufReader::new(file),
            left,
            started: false,
            done: false,
            chunk: Vec::new(),
            chunk_at: 0,
            after_chunk: None,
            topics: Topics { schemas: HashMap::new(), channels: HashMap::new(), wanted },
        })
    }

    /// The error `cause`, after which nothing more is read.
    fn fail(&mut self, cause: impl std::fmt::Display) -> BagError {
        self.done = true;
        mcap_error(&self.path, cause)
    }

    /// The next `n` bytes of the file (`n` at most what is left).
    fn bytes(&mut self, n: u64) -> Result<Vec<u8>, BagError> {
        let mut out = Vec::new();
        (&mut self.file).take(n).read_to_end(&mut out).map_err(|cause| {
            self.done = true;
            BagError::Io { path: self.path.clone(), cause }
        })?;
        self.left = self.left.saturating_sub(out.len() as u64);
        if (out.len() as u64) < n {
            return Err(self.fail("the file ended while it was read (it shrank)"));
        }
        Ok(out)
    }

    /// The next wanted message, `None` at the end of the file.
    pub fn next_message(&mut self) -> Result<Option<BagMessage>, BagError> {
        loop {
            // the chunk being read first
            loop {
                let (opcode, body) = match next_chunk_record(&self.chunk, &mut self.chunk_at) {
                    Ok(Some(record)) => record,
                    Ok(None) => break,
                    Err(e) => return Err(self.fail(e)),
                };
                if let Some(m) = self.topics.take(opcode, body).map_err(|e| self.fail(e))? {
                    return Ok(Some(m));
                }
            }
            self.chunk.clear();
            self.chunk_at = 0;
            if let Some(e) = self.after_chunk.take() {
                return Err(self.fail(e));
            }
            if self.done {
                return Ok(None);
            }
            if !self.started {
                let magic = self.bytes(self.left.min(mcap::MAGIC.len() as u64))?;
                if magic != mcap::MAGIC {
                    return Err(self.fail("no MCAP magic at its start"));
                }
                self.started = true;
            }
            if self.left < 9 {
                return Err(self.fail("the file ends before its footer: cut short"));
            }
            let head = self.bytes(9)?;
            let opcode = head[0];
            let len = u64::from_le_bytes(head[1..9].try_into().unwrap_or_default());
            if len > MAX_RECORD_BYTES as u64 {
                return Err(self.fail(format!("a record of {len} bytes (at most {MAX_RECORD_BYTES} are read)")));
            }
            if len > self.left {
                let missing = len - self.left;
                if opcode != mcap::records::op::CHUNK {
                    return Err(self.fail(format!("a record cut short: the file ends {missing} bytes before its end")));
                }
                // the records before the cut, then the error
                let body = self.bytes(self.left)?;
                self.chunk = Chunk::parse(&body, true).map(|c| c.records_before_the_cut()).unwrap_or_default();
                self.after_chunk = Some(format!("a chunk cut short: the file ends {missing} bytes before its end"));
                continue;
            }
            let body = self.bytes(len)?;
            match opcode {
                mcap::records::op::CHUNK => {
                    self.chunk = Chunk::parse(&body, false).and_then(|c| c.records()).map_err(|e| self.fail(e))?;
                }
                // the data section's end: the summary after it repeats what was read
                mcap::records::op::DATA_END | mcap::records::op::FOOTER => {
                    self.done = true;
                    return Ok(None);
                }
                _ => {
                    if let Some(m) = self.topics.take(opcode, &body).map_err(|e| self.fail(e))? {
                        return Ok(Some(m));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// An MCAP file of `n` messages of 40 bytes on `/scan`, in chunks compressed as `compression`.
    fn file(compression: Option<mcap::Compression>, n: u32) -> Vec<u8> {
        let mut out = Vec::new();
        let mut w = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(Some(1 << 20))
            .create(std::io::Cursor::new(&mut out))
            .expect("a writer");
        let schema = w.add_schema("sensor_msgs/msg/LaserScan", "ros2msg", b"").expect("a schema");
        let channel = w.add_channel(schema, "/scan", "cdr", &BTreeMap::new()).expect("a channel");
        for k in 0..n {
            let header =
                mcap::records::MessageHeader { channel_id: channel, sequence: k, log_time: k.into(), publish_time: 0 };
            // bytes that do not compress away
            let data: Vec<u8> =
                (0..40u32).map(|i| (k.wrapping_mul(2654435761) ^ i.wrapping_mul(40503)) as u8).collect();
            w.write_to_known_channel(&header, &data).expect("a message");
        }
        w.finish().expect("the summary");
        drop(w);
        out
    }

    /// The messages read from `bytes` before the end or an error, and the error.
    fn read(bytes: &[u8]) -> (usize, Option<String>) {
        let dir = tempfile::tempdir().expect("a scratch folder");
        let path = dir.path().join("t.mcap");
        std::fs::write(&path, bytes).expect("written");
        let mut f = McapFile::open(&path, Vec::new()).expect("opened");
        let mut n = 0;
        loop {
            match f.next_message() {
                Ok(Some(_)) => n += 1,
                Ok(None) => return (n, None),
                Err(e) => return (n, Some(e.to_string())),
            }
        }
    }

    /// Where the first chunk record starts (its opcode).
    fn first_chunk(bytes: &[u8]) -> usize {
        let mut at = 8; // the magic
        while bytes[at] != mcap::records::op::CHUNK {
            at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        }
        at
    }

    /// A file of 20 messages whose first chunk, compressed as `c`, declares 64 bytes more than
    /// its records hold (one damaged length field), and where that chunk starts.
    fn declaring_more(c: mcap::Compression) -> (Vec<u8>, usize) {
        let mut bytes = file(Some(c), 20);
        // the chunk's body: start time, end time, then the uncompressed size
        let chunk = first_chunk(&bytes);
        let size_at = chunk + 9 + 16;
        let size = u64::from_le_bytes(bytes[size_at..size_at + 8].try_into().unwrap());
        bytes[size_at..size_at + 8].copy_from_slice(&(size + 64).to_le_bytes());
        (bytes, chunk)
    }

    #[test]
    fn every_compression_reads_back_every_message() {
        for c in [None, Some(mcap::Compression::Zstd), Some(mcap::Compression::Lz4)] {
            assert_eq!(read(&file(c, 50)), (50, None), "{c:?}");
        }
    }

    /// A chunk whose records end before the size it declares: the `mcap` crate's own
    /// streaming decompression spun for ever on it, zstd and LZ4 alike.
    #[test]
    fn a_chunk_declaring_more_than_it_holds_is_an_error_not_a_hang() {
        for c in [mcap::Compression::Lz4, mcap::Compression::Zstd] {
            let (n, e) = read(&declaring_more(c).0);
            assert_eq!(n, 0, "{c:?}");
            assert!(e.as_deref().is_some_and(|e| e.contains("declares")), "{c:?}: {e:?}");
        }
    }

    /// The same damaged chunk where the footer says the summary starts: the `mcap` crate's
    /// summary reader decompressed it and spun for ever (mcap 0.25, found by the fuzzer).
    /// Listing the topics is an error, within a bound.
    #[test]
    fn a_summary_at_a_chunk_declaring_more_than_it_holds_is_an_error_not_a_hang() {
        for c in [mcap::Compression::Lz4, mcap::Compression::Zstd] {
            let (mut bytes, chunk) = declaring_more(c);
            // the footer, before the closing magic: opcode, length, summary start, summary
            // offset start, summary CRC (0: none)
            let footer = bytes.len() - 8 - 29;
            assert_eq!(bytes[footer], mcap::records::op::FOOTER);
            bytes[footer + 9..footer + 17].copy_from_slice(&(chunk as u64).to_le_bytes());
            bytes[footer + 17..footer + 29].fill(0);
            let dir = tempfile::tempdir().expect("a scratch folder");
            let path = dir.path().join("t.mcap");
            std::fs::write(&path, &bytes).expect("written");
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let _ = tx.send(topics(&path).map(|t| t.len()));
                drop(dir);
            });
            let listed = rx.recv_timeout(std::time::Duration::from_secs(30));
            assert!(matches!(listed, Ok(Err(_))), "{c:?}: {listed:?}");
        }
    }

    #[test]
    fn a_damaged_chunk_fails_its_crc() {
        let mut bytes = file(None, 20);
        let at = first_chunk(&bytes);
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        // the last message's last byte
        bytes[at + 9 + len - 1] ^= 0x55;
        let (n, e) = read(&bytes);
        assert_eq!(n, 0);
        assert!(e.as_deref().is_some_and(|e| e.contains("CRC")), "{e:?}");
    }

    /// A record claiming more than any bag holds is an error before anything of its claimed
    /// size is allocated; one claiming more than the file holds is a file cut short.
    #[test]
    fn a_record_longer_than_the_file_is_an_error_not_an_allocation() {
        for claim in [1u64 << 28, 1 << 40, u64::MAX - 9] {
            let mut bytes = file(Some(mcap::Compression::Zstd), 20);
            let at = first_chunk(&bytes);
            bytes[at + 1..at + 9].copy_from_slice(&claim.to_le_bytes());
            let (n, e) = read(&bytes);
            let e = e.unwrap_or_default();
            if claim > MAX_RECORD_BYTES as u64 {
                assert!(n == 0 && e.contains("at most"), "{claim}: {n} {e}");
            } else {
                assert!(e.contains("cut short"), "{claim}: {n} {e}");
            }
        }
    }

    /// A recording killed inside a chunk: the whole messages before the cut, then the error.
    #[test]
    fn a_file_cut_inside_a_chunk_gives_the_messages_before_the_cut() {
        for c in [None, Some(mcap::Compression::Zstd), Some(mcap::Compression::Lz4)] {
            // about 500 KB of records in one chunk: 128 KB zstd blocks, 64 KB LZ4 ones, of
            // which those wholly before the cut decompress
            let bytes = file(c, 8000);
            let at = first_chunk(&bytes);
            let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
            let (n, e) = read(&bytes[..at + 9 + len * 3 / 4]);
            assert!((1000..8000).contains(&n), "{c:?}: {n} messages");
            assert!(e.is_some_and(|e| e.contains("cut short")), "{c:?}");
        }
    }
}
