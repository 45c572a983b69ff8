//! CDR as ROS 2 puts it on the wire (OMG CDR, little endian): a 4-byte encapsulation header
//! `00 01 00 00`, then each primitive aligned to its own size (at most 8) counted from the end
//! of that header; strings as a `u32` length that counts a terminating NUL, the bytes and the
//! NUL; sequences as a `u32` count and the elements; fixed arrays as the elements alone.
//!
//! In: values (writer) or bytes from outside (reader, every length checked against what is
//! left before anything is allocated). Out: bytes, or a [`CdrError`] saying what and where.

/// The encapsulation header of little-endian plain CDR (`CDR_LE`).
pub const HEADER_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CdrError {
    #[error("{0} bytes: shorter than the 4-byte CDR header")]
    NoHeader(usize),
    #[error("encapsulation {0:02x} {1:02x} is not little-endian CDR (00 01)")]
    Encapsulation(u8, u8),
    #[error("ends at byte {at} while reading {what}")]
    Short { at: usize, what: &'static str },
    #[error("{what} at byte {at}: {len} is more than the {max} allowed")]
    TooLong {
        at: usize,
        what: &'static str,
        len: usize,
        max: usize,
    },
    #[error("string at byte {0} is not UTF-8 or lacks its terminating NUL")]
    BadString(usize),
}

/// Builds one CDR message, header included.
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    pub fn new() -> Self {
        Self {
            buf: HEADER_LE.to_vec(),
        }
    }

    fn align(&mut self, n: usize) {
        while !(self.buf.len() - HEADER_LE.len()).is_multiple_of(n) {
            self.buf.push(0);
        }
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A sequence's or string's length (saturated: Kestrel never writes 4 G elements).
    pub fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    pub fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// An `int8[]` sequence.
    pub fn i8_seq(&mut self, data: &[i8]) {
        self.len(data.len());
        self.buf.extend(data.iter().map(|&v| v.to_le_bytes()[0]));
    }

    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads one CDR message from bytes of unknown origin.
pub struct CdrReader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the header: only little-endian plain CDR is read.
    pub fn new(buf: &'a [u8]) -> Result<Self, CdrError> {
        let [a, b, _, _] = *buf
            .first_chunk::<4>()
            .ok_or(CdrError::NoHeader(buf.len()))?;
        if [a, b] != [HEADER_LE[0], HEADER_LE[1]] {
            return Err(CdrError::Encapsulation(a, b));
        }
        Ok(Self { buf, at: 4 })
    }

    fn take(&mut self, n: usize, align: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let pad = (align - (self.at - HEADER_LE.len()) % align) % align;
        let start = self.at + pad;
        let bytes = self
            .buf
            .get(start..start.saturating_add(n))
            .ok_or(CdrError::Short { at: self.at, what })?;
        self.at = start + n;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        let bytes = self.take(N, N, what)?;
        let mut out = [0; N];
        out.copy_from_slice(bytes);
        Ok(out)
    }

    pub fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    pub fn i32(&mut self, what: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    pub fn f64(&mut self, what: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// A string of at most `max` bytes (its NUL not counted).
    pub fn string(&mut self, what: &'static str, max: usize) -> Result<String, CdrError> {
        let at = self.at;
        let len = self.u32(what)? as usize;
        if len > max + 1 {
            return Err(CdrError::TooLong { at, what, len, max });
        }
        let bytes = self.take(len, 1, what)?;
        match bytes.split_last() {
            Some((0, text)) => std::str::from_utf8(text)
                .map(str::to_string)
                .map_err(|_| CdrError::BadString(at)),
            // An empty string written without even its NUL (some writers do).
            None => Ok(String::new()),
            Some(_) => Err(CdrError::BadString(at)),
        }
    }

    /// Where the reader is (bytes from the start, header included).
    pub fn position(&self) -> usize {
        self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_are_aligned_from_the_end_of_the_header() {
        let mut w = CdrWriter::new();
        w.u32(7);
        w.f64(1.0);
        w.string("ab");
        w.f64(-2.0);
        let bytes = w.finish();
        let expected: Vec<u8> = [
            &HEADER_LE[..],
            &[7, 0, 0, 0],                // 0: u32
            &[0, 0, 0, 0],                // 4: pad to 8
            &1.0f64.to_le_bytes(),        // 8: f64
            &[3, 0, 0, 0, b'a', b'b', 0], // 16: length 3 with the NUL, "ab", NUL
            &[0],                         // 23: pad to 24
            &(-2.0f64).to_le_bytes(),     // 24: f64
        ]
        .concat();
        assert_eq!(bytes, expected);
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.u32("a").unwrap(), 7);
        assert_eq!(r.f64("b").unwrap(), 1.0);
        assert_eq!(r.string("c", 8).unwrap(), "ab");
        assert_eq!(r.f64("d").unwrap(), -2.0);
        assert_eq!(r.position(), bytes.len());
    }

    #[test]
    fn hostile_bytes_are_refused_with_where() {
        assert_eq!(CdrReader::new(&[0, 1]).err(), Some(CdrError::NoHeader(2)));
        assert_eq!(
            CdrReader::new(&[0, 0, 0, 0]).err(),
            Some(CdrError::Encapsulation(0, 0))
        );
        let mut r = CdrReader::new(&[0, 1, 0, 0, 1, 2]).unwrap();
        assert_eq!(
            r.u32("count"),
            Err(CdrError::Short {
                at: 4,
                what: "count"
            })
        );
        // A string announcing 4 GB is refused before anything is read or allocated.
        let huge = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff];
        let mut r = CdrReader::new(&huge).unwrap();
        assert!(matches!(
            r.string("frame_id", 256),
            Err(CdrError::TooLong { at: 4, .. })
        ));
        let no_nul = [0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b'];
        let mut r = CdrReader::new(&no_nul).unwrap();
        assert_eq!(r.string("frame_id", 256), Err(CdrError::BadString(4)));
    }
}
