//! Where a bag's messages are and how one is read back: chunk records (their compression,
//! sizes and file offset), message places (a range of a decompressed chunk, or of the file for
//! a message outside chunks) and [`ChunkReader`], which seeks to a chunk, decompresses it (zstd
//! or lz4, both pure Rust for lz4: `lz4_flex`) and keeps the most recent ones in a cache of at
//! most [`CACHE_BYTES`].

use std::collections::VecDeque;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;
use std::sync::{Arc, Mutex};

/// The most decompressed chunk bytes [`ChunkReader`] keeps (the chunk just read is kept even
/// when it alone is larger).
pub const CACHE_BYTES: usize = 16 << 20;

/// The compression of a chunk's records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// Stored as is (`""`).
    None,
    /// `zstd`.
    Zstd,
    /// `lz4` (the LZ4 frame format).
    Lz4,
}

impl Compression {
    /// The compression named `name` in a chunk record, `None` for one this reader lacks.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "" => Some(Self::None),
            "zstd" => Some(Self::Zstd),
            "lz4" => Some(Self::Lz4),
            _ => None,
        }
    }
}

/// The compressions [`Compression::parse`] knows, as errors list them.
pub const SUPPORTED: &str = "zstd, lz4, none";

/// One chunk record: where its compressed records start in the file and their sizes.
#[derive(Debug, Clone, Copy)]
pub struct ChunkRef {
    /// File offset of the compressed records.
    pub offset: u64,
    /// Compressed size, bytes.
    pub compressed: u64,
    /// Decompressed size, bytes.
    pub uncompressed: u64,
    /// How the records are compressed.
    pub compression: Compression,
}

/// Where a message's CDR bytes are.
#[derive(Debug, Clone)]
pub enum Place {
    /// Bytes `range` of the decompressed chunk `chunk` (an index into the chunk list).
    Chunk {
        /// The chunk.
        chunk: usize,
        /// The message's bytes in it.
        range: Range<usize>,
    },
    /// `len` bytes at file offset `offset` (a message outside chunks).
    File {
        /// File offset.
        offset: u64,
        /// Length, bytes.
        len: usize,
    },
}

/// Decompresses a chunk's `data` to exactly `uncompressed` bytes.
pub fn decompress(
    compression: Compression,
    data: &[u8],
    uncompressed: u64,
) -> Result<Vec<u8>, String> {
    let limit = uncompressed.saturating_add(1);
    let capacity = usize::try_from(uncompressed)
        .unwrap_or(usize::MAX)
        .min(data.len().saturating_mul(8).max(1 << 16));
    let mut out = Vec::with_capacity(capacity);
    let read = match compression {
        Compression::None => {
            out.extend_from_slice(data);
            Ok(data.len())
        }
        Compression::Zstd => {
            zstd::stream::read::Decoder::new(data).and_then(|d| d.take(limit).read_to_end(&mut out))
        }
        Compression::Lz4 => lz4_flex::frame::FrameDecoder::new(data)
            .take(limit)
            .read_to_end(&mut out),
    };
    read.map_err(|e| format!("{compression:?} decompression failed: {e}"))?;
    if out.len() as u64 != uncompressed {
        return Err(format!(
            "the chunk decompresses to {} bytes, its header says {uncompressed}",
            out.len()
        ));
    }
    Ok(out)
}

/// Reads messages back from their [`Place`]: one file handle, and the decompressed chunks
/// read last (at most [`CACHE_BYTES`] of them, oldest dropped first).
pub struct ChunkReader {
    file: Mutex<File>,
    chunks: Vec<ChunkRef>,
    cache: Mutex<VecDeque<(usize, Arc<Vec<u8>>)>>,
}

/// A message's bytes: a range of a decompressed chunk (shared with the cache) or its own.
pub struct MessageBytes {
    buffer: Arc<Vec<u8>>,
    range: Range<usize>,
}

impl MessageBytes {
    /// The CDR bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.buffer[self.range.clone()]
    }
}

impl ChunkReader {
    /// A reader of `file`'s messages in `chunks`.
    pub fn new(file: File, chunks: Vec<ChunkRef>) -> Self {
        Self {
            file: Mutex::new(file),
            chunks,
            cache: Mutex::new(VecDeque::new()),
        }
    }

    /// Decompressed chunks held by the cache now, and their bytes.
    pub fn cached(&self) -> (usize, usize) {
        let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        (cache.len(), cache.iter().map(|(_, b)| b.len()).sum())
    }

    fn read_at(&self, offset: u64, len: u64) -> Result<Vec<u8>, String> {
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        let mut out = Vec::new();
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| (&mut *file).take(len).read_to_end(&mut out))
            .map_err(|e| format!("reading {len} bytes at byte {offset}: {e}"))?;
        if out.len() as u64 != len {
            return Err(format!(
                "the file ends {} bytes into the {len} bytes at byte {offset}",
                out.len()
            ));
        }
        Ok(out)
    }

    /// The decompressed chunk `index`, from the cache or the file.
    fn chunk(&self, index: usize) -> Result<Arc<Vec<u8>>, String> {
        {
            let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((_, b)) = cache.iter().find(|(i, _)| *i == index) {
                return Ok(Arc::clone(b));
            }
        }
        let c = self
            .chunks
            .get(index)
            .ok_or_else(|| format!("no chunk {index}"))?;
        let data = self.read_at(c.offset, c.compressed)?;
        let records = Arc::new(decompress(c.compression, &data, c.uncompressed)?);
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        cache.push_back((index, Arc::clone(&records)));
        while cache.len() > 1 && cache.iter().map(|(_, b)| b.len()).sum::<usize>() > CACHE_BYTES {
            cache.pop_front();
        }
        Ok(records)
    }

    /// The bytes of the message at `place`; the error says what could not be read.
    pub fn message(&self, place: &Place) -> Result<MessageBytes, String> {
        match place {
            Place::Chunk { chunk, range } => {
                let buffer = self.chunk(*chunk)?;
                if range.end > buffer.len() {
                    return Err(format!("chunk {chunk} holds no bytes {range:?}"));
                }
                Ok(MessageBytes {
                    buffer,
                    range: range.clone(),
                })
            }
            Place::File { offset, len } => {
                let buffer = Arc::new(self.read_at(*offset, *len as u64)?);
                Ok(MessageBytes {
                    range: 0..buffer.len(),
                    buffer,
                })
            }
        }
    }
}
