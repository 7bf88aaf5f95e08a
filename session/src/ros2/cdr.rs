//! [`CdrWriter`]: a little-endian plain CDR (XCDR1) encoder, as ROS 2 uses
//! it for its messages.
//!
//! The stream starts with the 4-byte RTPS encapsulation header
//! `00 01 00 00` (`CDR_LE`: representation identifier `0x0001`, options 0;
//! DDSI-RTPS 2.5 §10.2, DDS-XTypes 1.3 §7.6.3.1.2). After it, each primitive
//! is aligned to its own size (1, 2, 4 or 8 bytes) counted from the end of
//! the header, with zero padding (XCDR1: 8-byte types align to 8,
//! DDS-XTypes 1.3 §7.4.1.1.1). Strings are a `u32` length counting a
//! trailing NUL, the bytes and the NUL; sequences a `u32` element count and
//! the elements; fixed-size arrays the elements alone; nested messages
//! their fields in order, with no padding of their own. This is what ROS 2's
//! default middleware (Fast DDS, Cyclone DDS) writes for `.msg` types, and
//! what `rosbags` and `rosbag2` read.

/// The encapsulation header of a little-endian plain CDR stream.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Builds one CDR-encoded message (see the module documentation).
#[derive(Clone, Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        CdrWriter::new()
    }
}

impl CdrWriter {
    /// An empty message (the encapsulation header alone).
    pub fn new() -> CdrWriter {
        CdrWriter { buf: CDR_LE_HEADER.to_vec() }
    }

    /// Pads with zeros to a multiple of `size` after the header.
    fn align(&mut self, size: usize) {
        let offset = self.buf.len() - CDR_LE_HEADER.len();
        let pad = (size - offset % size) % size;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.u8(u8::from(v))
    }

    /// `uint8` / `byte`.
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }

    /// `uint16`.
    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// `uint64`.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// The `u32` length of a sequence or string. Lengths are at most
    /// `u32::MAX` by the encoding; a longer one is a caller's bug.
    fn length(&mut self, n: usize) -> &mut Self {
        self.u32(u32::try_from(n).expect("a CDR sequence holds at most u32::MAX elements"))
    }

    /// `string`: length with the NUL, bytes, NUL.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.length(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
        self
    }

    /// `uint8[]`: length, bytes.
    pub fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.length(v.len());
        self.buf.extend_from_slice(v);
        self
    }

    /// `uint16[]`: length, elements.
    pub fn u16_seq(&mut self, v: &[u16]) -> &mut Self {
        self.length(v.len());
        v.iter().for_each(|x| {
            self.u16(*x);
        });
        self
    }

    /// `float64[]`: length, elements.
    pub fn f64_seq(&mut self, v: &[f64]) -> &mut Self {
        self.length(v.len());
        self.f64_array(v)
    }

    /// `float64[N]`: the elements alone.
    pub fn f64_array(&mut self, v: &[f64]) -> &mut Self {
        v.iter().for_each(|x| {
            self.f64(*x);
        });
        self
    }

    /// The length of a sequence of messages (the caller writes each).
    pub fn seq_len(&mut self, n: usize) -> &mut Self {
        self.length(n)
    }

    /// The encoded message.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_align_to_their_size_after_the_header() {
        let mut w = CdrWriter::new();
        w.u8(1).u16(0x0203).u8(4).u32(0x0506_0708).u8(9).f64(1.0);
        let expected: Vec<u8> = [
            &CDR_LE_HEADER[..],
            &[1, 0, 3, 2], // u8, pad to 2, u16
            &[4, 0, 0, 0], // u8, pad to 4
            &[8, 7, 6, 5], // u32
            &[9, 0, 0, 0], // u8 at 12, pad to 16
            &1.0f64.to_le_bytes(),
        ]
        .concat();
        assert_eq!(w.finish(), expected);
    }

    #[test]
    fn strings_count_their_nul_and_sequences_their_elements() {
        let mut w = CdrWriter::new();
        w.string("ab").u16_seq(&[1, 2]).string("").f64_seq(&[0.5]);
        let expected: Vec<u8> = [
            &CDR_LE_HEADER[..],
            &[3, 0, 0, 0, b'a', b'b', 0], // "ab" with its NUL
            &[0],                         // pad to 4
            &[2, 0, 0, 0, 1, 0, 2, 0],    // two u16
            &[1, 0, 0, 0, 0],             // "" is the NUL alone
            &[0, 0, 0],                   // pad to 4
            &[1, 0, 0, 0],                // one f64 (its length at offset 20)
            &[0, 0, 0, 0],                // pad to 8
            &0.5f64.to_le_bytes(),
        ]
        .concat();
        assert_eq!(w.finish(), expected);
    }

    #[test]
    fn a_header_then_bytes_as_ros_writes_a_compressed_image() {
        // std_msgs/Header { stamp { sec 1, nanosec 2 }, frame_id "c" }, format "png", data [7].
        let mut w = CdrWriter::new();
        w.i32(1).u32(2).string("c").string("png").bytes(&[7]);
        let expected: Vec<u8> = [
            &CDR_LE_HEADER[..],
            &[1, 0, 0, 0, 2, 0, 0, 0],
            &[2, 0, 0, 0, b'c', 0, 0, 0],
            &[4, 0, 0, 0, b'p', b'n', b'g', 0],
            &[1, 0, 0, 0, 7],
        ]
        .concat();
        assert_eq!(w.finish(), expected);
    }
}
