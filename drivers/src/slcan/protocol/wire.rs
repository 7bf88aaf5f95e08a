//! The bytes and limits of the SLCAN wire that the encoder, the decoder
//! and the timestamp unwrapping share.

/// Ends every command and every line the adapter sends; alone it is "OK".
pub const CR: u8 = b'\r';
/// The adapter's "error" reply (ASCII BEL).
pub const BEL: u8 = 0x07;
/// Longest line the decoder holds (bytes, terminator excluded). The longest
/// frame line is 30 bytes (`T` + 8 + 1 + 16 + 4); version strings of some
/// firmwares are longer. A longer line is dropped.
pub const MAX_LINE: usize = 128;
/// The adapter's timestamps count milliseconds modulo this (one minute).
pub const TIMESTAMP_PERIOD_MS: u16 = 60_000;
