//! A reader of OMG CDR (XCDR1), the serialisation of ROS 2 messages.
//!
//! A serialised message starts with a 4-byte encapsulation header: `00 00` (big-endian CDR) or
//! `00 01` (little-endian CDR), then two option bytes. Every primitive of `n` bytes is aligned
//! to a multiple of `n` counted from the end of that header (padding is skipped); a string is
//! a `u32` length that counts its terminating NUL, then the bytes; a sequence is a `u32` count,
//! then the elements.

use thiserror::Error;

/// Why a CDR message could not be read.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    /// The message ends before a field (`offset` in bytes from the message start).
    #[error("the message ends at byte {len}, a field at byte {offset} needs {need} bytes")]
    Truncated {
        /// Where the field starts.
        offset: usize,
        /// Its size.
        need: usize,
        /// The message length.
        len: usize,
    },
    /// The encapsulation header is not plain CDR (big- or little-endian).
    #[error("encapsulation {0:#06x} is not plain CDR (0x0000 big-endian or 0x0001 little-endian)")]
    Encapsulation(u16),
    /// A string is not NUL-terminated UTF-8.
    #[error("the string at byte {0} is not NUL-terminated UTF-8")]
    BadString(usize),
}

/// A cursor over one CDR message (after its encapsulation header).
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    little_endian: bool,
}

/// Length of the encapsulation header; alignment counts from its end.
const HEADER: usize = 4;

impl<'a> CdrReader<'a> {
    /// A reader of `bytes`, a whole message with its encapsulation header.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let header = bytes.get(..HEADER).ok_or(CdrError::Truncated {
            offset: 0,
            need: HEADER,
            len: bytes.len(),
        })?;
        let kind = u16::from_be_bytes([header[0], header[1]]);
        let little_endian = match kind {
            0x0000 => false,
            0x0001 => true,
            other => return Err(CdrError::Encapsulation(other)),
        };
        Ok(Self {
            bytes,
            pos: HEADER,
            little_endian,
        })
    }

    /// True when the message is little-endian.
    pub fn little_endian(&self) -> bool {
        self.little_endian
    }

    /// The next `n` bytes, after aligning to `align` (a power of two).
    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8], CdrError> {
        let rel = self.pos - HEADER;
        let start = self.pos + (align - rel % align) % align;
        let out = start
            .checked_add(n)
            .and_then(|end| self.bytes.get(start..end))
            .ok_or(CdrError::Truncated {
                offset: start,
                need: n,
                len: self.bytes.len(),
            })?;
        self.pos = start + n;
        Ok(out)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N, N)?);
        if self.little_endian != cfg!(target_endian = "little") {
            a.reverse();
        }
        Ok(a)
    }

    /// A `uint8` (also `bool` and `char`).
    pub fn u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take(1, 1)?[0])
    }

    /// A `uint32`.
    pub fn u32(&mut self) -> Result<u32, CdrError> {
        self.array::<4>().map(u32::from_ne_bytes)
    }

    /// An `int32`.
    pub fn i32(&mut self) -> Result<i32, CdrError> {
        self.array::<4>().map(i32::from_ne_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self) -> Result<f64, CdrError> {
        self.array::<8>().map(f64::from_ne_bytes)
    }

    /// A `string`: `u32` length with the NUL, the bytes, the NUL.
    pub fn string(&mut self) -> Result<&'a str, CdrError> {
        let at = self.pos;
        let len = self.u32()? as usize;
        if len == 0 {
            return Ok("");
        }
        let bytes = self.take(len, 1)?;
        match bytes.split_last() {
            Some((0, text)) => std::str::from_utf8(text).map_err(|_| CdrError::BadString(at)),
            _ => Err(CdrError::BadString(at)),
        }
    }

    /// A `uint8[]` sequence, borrowed.
    pub fn bytes(&mut self) -> Result<&'a [u8], CdrError> {
        let len = self.u32()? as usize;
        self.take(len, 1)
    }

    /// A `float64[]` sequence.
    pub fn f64_seq(&mut self) -> Result<Vec<f64>, CdrError> {
        let len = self.u32()? as usize;
        if len.saturating_mul(8) > self.bytes.len() {
            return Err(CdrError::Truncated {
                offset: self.pos,
                need: len.saturating_mul(8),
                len: self.bytes.len(),
            });
        }
        (0..len).map(|_| self.f64()).collect()
    }

    /// A `float64[N]` array.
    pub fn f64_array<const N: usize>(&mut self) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64()?;
        }
        Ok(out)
    }
}

/// A CDR writer (little-endian unless made with [`CdrWriter::big_endian`]), for tests and
/// writers of bags.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    bytes: Vec<u8>,
    big_endian: bool,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty little-endian message (its encapsulation header written).
    pub fn new() -> Self {
        Self {
            bytes: vec![0, 1, 0, 0],
            big_endian: false,
        }
    }

    /// An empty big-endian message (its encapsulation header written).
    pub fn big_endian() -> Self {
        Self {
            bytes: vec![0, 0, 0, 0],
            big_endian: true,
        }
    }

    fn put<const N: usize>(&mut self, le: [u8; N]) -> &mut Self {
        self.align(N);
        if self.big_endian {
            self.bytes.extend(le.iter().rev());
        } else {
            self.bytes.extend_from_slice(&le);
        }
        self
    }

    fn align(&mut self, n: usize) {
        while !(self.bytes.len() - HEADER).is_multiple_of(n) {
            self.bytes.push(0);
        }
    }

    /// A `uint8`.
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.bytes.push(v);
        self
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.put(v.to_le_bytes())
    }

    /// A `string` (length with its NUL).
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
        self
    }

    /// A `uint8[]` sequence.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u32(b.len() as u32);
        self.bytes.extend_from_slice(b);
        self
    }

    /// A `float64[]` sequence (`seq`) or, without the count, a `float64[N]` array.
    pub fn f64s(&mut self, v: &[f64], seq: bool) -> &mut Self {
        if seq {
            self.u32(v.len() as u32);
        }
        for &x in v {
            self.f64(x);
        }
        self
    }

    /// The message bytes.
    pub fn finish(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn big_endian_with_alignment() {
        // BE header, u8 1, pad to 4, u32 7, pad to 8 (rel 8 already), f64 2.5, string "ab".
        let mut m = vec![0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 7];
        m.extend_from_slice(&2.5f64.to_be_bytes());
        m.extend_from_slice(&[0, 0, 0, 3, b'a', b'b', 0]);
        let mut r = CdrReader::new(&m).unwrap();
        assert!(!r.little_endian());
        assert_eq!(r.u8().unwrap(), 1);
        assert_eq!(r.u32().unwrap(), 7);
        assert_eq!(r.f64().unwrap(), 2.5);
        assert_eq!(r.string().unwrap(), "ab");
        assert!(matches!(r.u32(), Err(CdrError::Truncated { .. })));
    }

    #[test]
    fn writer_round_trips_and_rejects_other_encapsulations() {
        let m = CdrWriter::new()
            .u8(3)
            .f64(-1.0)
            .string("x")
            .bytes(&[9, 8])
            .finish();
        assert_eq!(m.len(), 4 + 8 + 8 + 6 + 2 + 4 + 2);
        let mut r = CdrReader::new(&m).unwrap();
        assert_eq!((r.u8().unwrap(), r.f64().unwrap()), (3, -1.0));
        assert_eq!(
            (r.string().unwrap(), r.bytes().unwrap()),
            ("x", &[9u8, 8][..])
        );
        let be = CdrWriter::big_endian().u8(3).f64(-1.0).finish();
        assert_eq!(&be[..4], &[0, 0, 0, 0]);
        assert_eq!(&be[12..], &(-1.0f64).to_be_bytes());
        assert_eq!(
            CdrReader::new(&be).unwrap().f64_array::<2>().unwrap()[1],
            -1.0
        );
        assert_eq!(
            CdrReader::new(&[0, 7, 0, 0]).unwrap_err(),
            CdrError::Encapsulation(7)
        );
    }
}
