//! [`CdrReader`]: reads the little-endian plain CDR (XCDR1) that
//! [`slidetrack_session::ros2::CdrWriter`] writes and ROS 2 publishers
//! send, after the 4-byte encapsulation header (which RustDDS strips from
//! received samples): each primitive aligned to its size counted from the
//! start of the body, strings a `u32` length counting the NUL, sequences a
//! `u32` count. Every read is bounds-checked; none panics.

use super::error::CdrError;

/// A cursor over one CDR body (the bytes after the encapsulation header).
pub struct CdrReader<'a> {
    body: &'a [u8],
    at: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader at the start of `body`.
    pub fn new(body: &'a [u8]) -> CdrReader<'a> {
        CdrReader { body, at: 0 }
    }

    /// Bytes not yet read.
    pub fn remaining(&self) -> usize {
        self.body.len() - self.at
    }

    /// Skips the padding before a primitive of `size` bytes, then takes it.
    fn take(&mut self, size: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        let start = self.at.div_ceil(size) * size;
        let end = start.checked_add(size).filter(|&e| e <= self.body.len());
        let Some(end) = end else {
            return Err(CdrError::Truncated { field, offset: self.at, len: self.body.len() });
        };
        self.at = end;
        Ok(&self.body[start..end])
    }

    /// `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(1, field)?[0])
    }

    /// `uint16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, CdrError> {
        let b = self.take(2, field)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    /// `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        let b = self.take(4, field)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// `float32`.
    pub fn f32(&mut self, field: &'static str) -> Result<f32, CdrError> {
        Ok(f32::from_bits(self.u32(field)?))
    }

    /// `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        let b = self.take(8, field)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    /// The `u32` count of a sequence whose elements take at least
    /// `min_element_bytes` each: a count the remaining bytes cannot hold
    /// is refused before anything is allocated for it.
    pub fn seq_len(&mut self, field: &'static str, min_element_bytes: usize) -> Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_element_bytes.max(1)) > self.remaining() {
            return Err(CdrError::Length { field, count: n as u64, remaining: self.remaining() });
        }
        Ok(n)
    }

    /// `string`: UTF-8 with its terminating NUL.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.seq_len(field, 1)?;
        let bytes = &self.body[self.at..self.at + n];
        self.at += n;
        let Some((&0, text)) = bytes.split_last() else {
            return Err(CdrError::NoNul { field });
        };
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::NotUtf8 { field })
    }
}

#[cfg(test)]
mod tests {
    use slidetrack_session::ros2::CdrWriter;

    use super::*;

    fn body(w: CdrWriter) -> Vec<u8> {
        w.finish()[4..].to_vec()
    }

    #[test]
    fn reads_back_what_the_writer_aligned() {
        let mut w = CdrWriter::new();
        w.u8(1).u16(0x0203).u8(4).u32(7).u8(9).f64(1.5).string("uSPa44").u16(65535);
        let b = body(w);
        let mut r = CdrReader::new(&b);
        assert_eq!(r.u8("a").unwrap(), 1);
        assert_eq!(r.u16("b").unwrap(), 0x0203);
        assert_eq!(r.u8("c").unwrap(), 4);
        assert_eq!(r.u32("d").unwrap(), 7);
        assert_eq!(r.u8("e").unwrap(), 9);
        assert_eq!(r.f64("f").unwrap(), 1.5);
        assert_eq!(r.string("g").unwrap(), "uSPa44");
        assert_eq!(r.u16("h").unwrap(), 65535);
        assert_eq!(r.remaining(), 0);
        assert!(matches!(r.u8("i"), Err(CdrError::Truncated { field: "i", .. })));
    }

    #[test]
    fn lengths_beyond_the_body_and_strings_without_nul_are_refused() {
        let mut r = CdrReader::new(&[0xff, 0xff, 0xff, 0xff, 0]);
        assert!(matches!(r.seq_len("s", 1), Err(CdrError::Length { count: 0xffff_ffff, .. })));
        let mut r = CdrReader::new(&[2, 0, 0, 0, b'a', b'b']);
        assert!(matches!(r.string("m"), Err(CdrError::NoNul { field: "m" })));
        let mut r = CdrReader::new(&[2, 0, 0, 0, 0xff, 0]);
        assert!(matches!(r.string("m"), Err(CdrError::NotUtf8 { field: "m" })));
        let mut r = CdrReader::new(&[0, 0, 0, 0]);
        assert!(matches!(r.string("m"), Err(CdrError::NoNul { .. })), "a string has at least its NUL");
    }
}
