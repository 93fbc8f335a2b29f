//! One pass over a bag that finds where each message of the image and calibration types is,
//! without keeping the messages: with a summary section, the chunks its chunk indexes list
//! that hold such a channel, in log-time order, each read and decompressed once; without one
//! (a bag cut off mid-file, or written without a summary), the records from the start, up to
//! the first damaged or missing one (a note says so). Only each topic's first message is
//! kept (its encoding and the calibration come from it).

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use mcap::records::{op, ChunkIndex, Record};

use super::chunks::{decompress, ChunkRef, Compression, Place};
use super::{messages, BagError};

/// One message of a kept topic: its index on the topic (log-time order), log time (ns),
/// stamp (s: the header stamp, else the log time) and place.
#[derive(Debug, Clone)]
pub struct Stored {
    /// Zero-based index on the topic, in log-time order.
    pub index: usize,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// Header stamp (the log time when the stamp is zero or unreadable), seconds.
    pub stamp: f64,
    /// Where its bytes are.
    pub place: Place,
}

/// A topic of a kept message type.
#[derive(Debug)]
pub struct Topic {
    /// Topic name.
    pub name: String,
    /// Schema name (`sensor_msgs/msg/Image`, ...).
    pub schema: String,
    /// The bytes of its first message read.
    pub first: Vec<u8>,
    /// Its messages, in log-time order.
    pub messages: Vec<Stored>,
}

/// What [`scan`] found.
#[derive(Debug)]
pub struct Scan {
    /// The chunks the places refer to.
    pub chunks: Vec<ChunkRef>,
    /// The kept topics by name.
    pub topics: HashMap<String, Topic>,
    /// What was left out (a cut, a damaged chunk).
    pub notes: Vec<String>,
    /// True when the summary's chunk indexes were used.
    pub indexed: bool,
}

/// The message types kept.
const WANTED: [&str; 3] = [
    messages::IMAGE,
    messages::COMPRESSED_IMAGE,
    messages::CAMERA_INFO,
];

/// A chunk that cannot be used.
enum ChunkError {
    /// A compression this reader lacks (its name).
    Unsupported(String),
    /// Damaged.
    Bad(String),
}

#[derive(Default)]
struct Scanner {
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, (String, u16, String)>,
    chunks: Vec<ChunkRef>,
    topics: HashMap<String, Topic>,
    notes: Vec<String>,
}

fn le_u64(b: &[u8], at: usize) -> Option<u64> {
    let bytes = b.get(at..at.checked_add(8)?)?;
    bytes.try_into().ok().map(u64::from_le_bytes)
}

fn le_u32(b: &[u8], at: usize) -> Option<u32> {
    let bytes = b.get(at..at.checked_add(4)?)?;
    bytes.try_into().ok().map(u32::from_le_bytes)
}

/// The records of `bytes` (opcode, body) up to the first one that does not fit.
fn records(bytes: &[u8]) -> impl Iterator<Item = (u8, usize, &[u8])> {
    let mut at = 0usize;
    std::iter::from_fn(move || {
        let op = *bytes.get(at)?;
        let len = usize::try_from(le_u64(bytes, at + 1)?).ok()?;
        let start = at + 9;
        let body = bytes.get(start..start.checked_add(len)?)?;
        at = start + len;
        Some((op, start, body))
    })
}

impl Scanner {
    /// Takes a schema or channel record in.
    fn definition(&mut self, op: u8, body: &[u8]) -> Result<(), String> {
        match mcap::read::parse_record(op, body).map_err(|e| e.to_string())? {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                self.channels
                    .insert(c.id, (c.topic, c.schema_id, c.message_encoding));
            }
            _ => {}
        }
        Ok(())
    }

    /// The topic and schema of a kept channel.
    fn wanted(&self, channel: u16) -> Option<(&str, &str)> {
        let (topic, schema_id, encoding) = self.channels.get(&channel)?;
        let schema = self.schemas.get(schema_id)?;
        (encoding == "cdr" && WANTED.contains(&schema.as_str()))
            .then_some((topic.as_str(), schema.as_str()))
    }

    /// Records a message record's `body` (at `place` once the 22-byte header is skipped).
    fn message(&mut self, body: &[u8], place: impl FnOnce(usize) -> Place) {
        let (Some(channel), Some(log_time)) = (
            body.get(..2).map(|b| u16::from_le_bytes([b[0], b[1]])),
            le_u64(body, 6),
        ) else {
            return;
        };
        let Some(data) = body.get(22..) else { return };
        let Some((name, schema)) = self.wanted(channel) else {
            return;
        };
        let (name, schema) = (name.to_owned(), schema.to_owned());
        let stamp = messages::stamp(data)
            .ok()
            .filter(|&t| t != 0.0)
            .unwrap_or(log_time as f64 / 1e9);
        let topic = self.topics.entry(name.clone()).or_insert_with(|| Topic {
            name,
            schema,
            first: data.to_vec(),
            messages: Vec::new(),
        });
        topic.messages.push(Stored {
            index: 0,
            log_time,
            stamp,
            place: place(data.len()),
        });
    }

    /// Reads a chunk record's `body` (the record starts at file offset `at`): decompresses
    /// its records and keeps the schemas, channels and the places of kept messages.
    fn chunk(&mut self, body: &[u8], at: u64) -> Result<(), ChunkError> {
        let bad = |what: &str| ChunkError::Bad(format!("chunk at byte {at}: {what}"));
        let uncompressed = le_u64(body, 16).ok_or_else(|| bad("short header"))?;
        let name_len = le_u32(body, 28).ok_or_else(|| bad("short header"))? as usize;
        let name = body
            .get(32..32usize.saturating_add(name_len))
            .ok_or_else(|| bad("short header"))?;
        let name = String::from_utf8_lossy(name).into_owned();
        let size_at = 32 + name_len;
        let compressed = le_u64(body, size_at).ok_or_else(|| bad("short header"))?;
        let start = size_at + 8;
        let data = usize::try_from(compressed)
            .ok()
            .and_then(|n| body.get(start..start.checked_add(n)?))
            .ok_or_else(|| bad("the compressed records overrun the record"))?;
        let compression = Compression::parse(&name).ok_or(ChunkError::Unsupported(name))?;
        let records_bytes = decompress(compression, data, uncompressed).map_err(|e| bad(&e))?;
        let chunk = self.chunks.len();
        self.chunks.push(ChunkRef {
            offset: at + 9 + start as u64,
            compressed,
            uncompressed,
            compression,
        });
        for (op, start, body) in records(&records_bytes) {
            match op {
                op::SCHEMA | op::CHANNEL => self.definition(op, body).map_err(|e| bad(&e))?,
                op::MESSAGE => self.message(body, |len| Place::Chunk {
                    chunk,
                    range: start + 22..start + 22 + len,
                }),
                _ => {}
            }
        }
        Ok(())
    }

    fn finish(mut self, indexed: bool) -> Scan {
        for topic in self.topics.values_mut() {
            topic.messages.sort_by_key(|m| m.log_time);
            for (i, m) in topic.messages.iter_mut().enumerate() {
                m.index = i;
            }
        }
        Scan {
            chunks: self.chunks,
            topics: self.topics,
            notes: self.notes,
            indexed,
        }
    }
}

/// Reads `len` bytes at `offset`, `None` when the file is shorter.
fn read_at(file: &mut File, offset: u64, len: u64) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    file.seek(SeekFrom::Start(offset)).ok()?;
    file.take(len).read_to_end(&mut out).ok()?;
    (out.len() as u64 == len).then_some(out)
}

/// The summary's chunk indexes (with its schemas and channels taken into `scanner`), `None`
/// when the file has no usable footer, summary or chunk index.
fn summary(file: &mut File, file_len: u64, scanner: &mut Scanner) -> Option<Vec<ChunkIndex>> {
    const FOOTER: u64 = 1 + 8 + 20;
    let magic = mcap::MAGIC.len() as u64;
    let footer_at = file_len.checked_sub(FOOTER + magic)?;
    let tail = read_at(file, footer_at, FOOTER + magic)?;
    if tail[..1] != [op::FOOTER] || le_u64(&tail, 1)? != 20 || !tail.ends_with(mcap::MAGIC) {
        return None;
    }
    let start = le_u64(&tail, 9)?;
    if start == 0 || start >= footer_at {
        return None;
    }
    let section = read_at(file, start, footer_at - start)?;
    let mut indexes = Vec::new();
    for (op, _, body) in records(&section) {
        match op {
            op::SCHEMA | op::CHANNEL => scanner.definition(op, body).ok()?,
            op::CHUNK_INDEX => match mcap::read::parse_record(op, body).ok()? {
                Record::ChunkIndex(c) => indexes.push(c),
                _ => return None,
            },
            _ => {}
        }
    }
    indexes.sort_by_key(|c| (c.message_start_time, c.chunk_start_offset));
    (!indexes.is_empty()).then_some(indexes)
}

/// Scans the bag at `path` (see the module documentation).
pub fn scan(path: &Path) -> Result<Scan, BagError> {
    let read_error = |message: String| BagError::Read {
        path: path.to_path_buf(),
        message,
    };
    let unsupported = |compression: String| BagError::Compression {
        path: path.to_path_buf(),
        compression,
    };
    let mut file = File::open(path).map_err(|e| read_error(e.to_string()))?;
    let file_len = file
        .metadata()
        .map_err(|e| read_error(e.to_string()))?
        .len();
    let magic = mcap::MAGIC.len() as u64;
    if read_at(&mut file, 0, magic).as_deref() != Some(mcap::MAGIC) {
        return Err(read_error("no MCAP magic at the start".into()));
    }
    let mut scanner = Scanner::default();
    if let Some(indexes) = summary(&mut file, file_len, &mut scanner) {
        for c in indexes {
            let holds_kept = c.message_index_offsets.is_empty()
                || c.message_index_offsets
                    .keys()
                    .any(|&id| scanner.wanted(id).is_some());
            if !holds_kept {
                continue;
            }
            let record = read_at(&mut file, c.chunk_start_offset, c.chunk_length)
                .filter(|r| r.len() > 9 && r[0] == op::CHUNK);
            let result = match &record {
                Some(r) => scanner.chunk(&r[9..], c.chunk_start_offset),
                None => Err(ChunkError::Bad(format!(
                    "chunk at byte {}: not a chunk record of {} bytes",
                    c.chunk_start_offset, c.chunk_length
                ))),
            };
            match result {
                Ok(()) => {}
                Err(ChunkError::Unsupported(name)) => return Err(unsupported(name)),
                Err(ChunkError::Bad(e)) => scanner.notes.push(format!(
                    "{}: {e}; its messages are left out",
                    path.display()
                )),
            }
        }
        return Ok(scanner.finish(true));
    }
    let cut = |scanner: &mut Scanner, why: String| {
        scanner.notes.push(format!(
            "{}: the bag ends early or is damaged ({why}); the messages before it are read",
            path.display()
        ));
    };
    file.seek(SeekFrom::Start(magic))
        .map_err(|e| read_error(e.to_string()))?;
    let mut reader = BufReader::new(file);
    let mut at = magic;
    loop {
        let mut head = [0u8; 9];
        if reader.read_exact(&mut head).is_err() {
            cut(
                &mut scanner,
                format!("no footer: the records stop at byte {at}"),
            );
            break;
        }
        let op = head[0];
        let len = le_u64(&head, 1).unwrap_or(u64::MAX);
        let body_at = at + 9;
        if len > file_len.saturating_sub(body_at) {
            cut(
                &mut scanner,
                format!("the record at byte {at} needs {len} bytes, the file ends before"),
            );
            break;
        }
        let mut body = Vec::new();
        let keep = matches!(op, op::CHUNK | op::MESSAGE | op::SCHEMA | op::CHANNEL);
        let read = if keep {
            (&mut reader).take(len).read_to_end(&mut body).map(|_| ())
        } else {
            i64::try_from(len)
                .map_err(std::io::Error::other)
                .and_then(|n| reader.seek_relative(n))
        };
        if let Err(e) = read {
            cut(
                &mut scanner,
                format!("reading the record at byte {at}: {e}"),
            );
            break;
        }
        match op {
            op::CHUNK => match scanner.chunk(&body, at) {
                Ok(()) => {}
                Err(ChunkError::Unsupported(name)) => return Err(unsupported(name)),
                Err(ChunkError::Bad(e)) => {
                    cut(&mut scanner, e);
                    break;
                }
            },
            op::MESSAGE => scanner.message(&body, |len| Place::File {
                offset: body_at + 22,
                len,
            }),
            op::SCHEMA | op::CHANNEL => {
                if let Err(e) = scanner.definition(op, &body) {
                    cut(&mut scanner, format!("record at byte {at}: {e}"));
                    break;
                }
            }
            op::FOOTER => break,
            _ => {}
        }
        at = body_at + len;
    }
    Ok(scanner.finish(false))
}
