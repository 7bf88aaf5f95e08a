//! Why a received `xela_server_ros2` sample does not decode.

/// A CDR body that is not a well-formed message.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The body ends inside a field.
    #[error("CDR: the message ends inside `{field}` (at byte {offset} of {len})")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Where its read started.
        offset: usize,
        /// The body's length.
        len: usize,
    },
    /// A sequence or string count larger than the bytes left.
    #[error("CDR: `{field}` claims {count} elements but only {remaining} bytes are left")]
    Length {
        /// The sequence.
        field: &'static str,
        /// Its count.
        count: u64,
        /// Bytes after the count.
        remaining: usize,
    },
    /// A string whose last byte is not NUL.
    #[error("CDR: string `{field}` does not end with NUL")]
    NoNul {
        /// The string.
        field: &'static str,
    },
    /// A string that is not UTF-8.
    #[error("CDR: string `{field}` is not UTF-8")]
    NotUtf8 {
        /// The string.
        field: &'static str,
    },
    /// Bytes left after the message.
    #[error("CDR: {extra} bytes after the end of the message")]
    Trailing {
        /// How many.
        extra: usize,
    },
}
