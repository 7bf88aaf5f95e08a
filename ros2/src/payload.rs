//! [`CdrPayload`]: a message already encoded by
//! [`slidetrack_session::ros2::CdrWriter`], handed to RustDDS as it is.

use rustdds::RepresentationIdentifier;
use rustdds::bytes::Bytes;
use rustdds::no_key::{Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter};
use slidetrack_session::ros2::CDR_LE_HEADER;

/// A plain little-endian CDR message without its 4-byte encapsulation
/// header (RustDDS writes the header from [`PlainCdrLe::output_encoding`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CdrPayload(Bytes);

impl CdrPayload {
    /// The payload of an encoded message; `None` unless it starts with the
    /// `CDR_LE` encapsulation header.
    pub fn from_cdr(message: Vec<u8>) -> Option<CdrPayload> {
        message
            .starts_with(&CDR_LE_HEADER)
            .then(|| CdrPayload(Bytes::from(message).slice(CDR_LE_HEADER.len()..)))
    }

    /// The CDR bytes after the encapsulation header.
    pub fn bytes(&self) -> &[u8] {
        &self.0
    }
}

/// RustDDS's serializer for [`CdrPayload`]: the bytes as they are, encoding `CDR_LE`.
#[derive(Debug)]
pub struct PlainCdrLe;

impl SerializerAdapter<CdrPayload> for PlainCdrLe {
    type Error = std::convert::Infallible;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &CdrPayload) -> Result<Bytes, Self::Error> {
        Ok(value.0.clone())
    }
}

/// Received bytes that are not little-endian plain CDR.
#[derive(Debug, thiserror::Error)]
#[error("a sample in {encoding:?}, not little-endian plain CDR (CDR_LE)")]
pub struct NotCdrLe {
    /// The sample's representation identifier.
    pub encoding: RepresentationIdentifier,
}

impl DeserializerAdapter<CdrPayload> for PlainCdrLe {
    type Error = NotCdrLe;
    type Decoded = CdrPayload;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[RepresentationIdentifier::CDR_LE]
    }

    fn transform_decoded(decoded: CdrPayload) -> CdrPayload {
        decoded
    }
}

/// Keeps a received sample's bytes as they are.
#[derive(Clone, Copy, Debug)]
pub struct KeepBytes;

impl Decode<'_, CdrPayload> for KeepBytes {
    type Error = NotCdrLe;

    fn decode_bytes(self, input: &[u8], encoding: RepresentationIdentifier) -> Result<CdrPayload, NotCdrLe> {
        if encoding == RepresentationIdentifier::CDR_LE {
            Ok(CdrPayload(Bytes::copy_from_slice(input)))
        } else {
            Err(NotCdrLe { encoding })
        }
    }
}

impl DefaultDecoder<CdrPayload> for PlainCdrLe {
    type Decoder = KeepBytes;
    const DECODER: KeepBytes = KeepBytes;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_is_left_to_rustdds_and_other_encodings_refused() {
        let p = CdrPayload::from_cdr(vec![0, 1, 0, 0, 7, 8]).unwrap();
        assert_eq!(PlainCdrLe::to_bytes(&p).unwrap().as_ref(), &[7, 8]);
        // Big-endian CDR (00 00) and a short buffer are not what CdrWriter writes.
        assert_eq!(CdrPayload::from_cdr(vec![0, 0, 0, 0, 7]), None);
        assert_eq!(CdrPayload::from_cdr(vec![0, 1]), None);
    }
}
