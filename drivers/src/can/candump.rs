//! The log format of can-utils' `candump -l` (and `log2asc`'s input), read
//! and written without I/O and without SocketCAN, so that captured CAN
//! traffic decodes on any machine; [`plain`] reads candump's console
//! output (`  can0  201   [8]  01 02 ...`). [`parse_any_line`] takes either.
//!
//! One record per line: `(SECONDS.MICROS) INTERFACE ID#DATA`, where `ID` is 3
//! hex digits for a standard frame and 8 for an extended one, and `DATA` is 0
//! to 8 bytes in hex. Remote frames are `ID#R` (optionally with a length),
//! CAN FD frames `ID##F` followed by up to 64 bytes, error frames carry the
//! error flag `0x20000000` in an 8-digit id (the format of can-utils'
//! `lib.c`, `sprint_canframe`).

pub mod plain;
mod record;

pub use record::{CandumpFrame, CandumpParseError, CandumpRecord};
use record::{ERROR_FLAG, bad, parse_seconds};

/// Parses one line (without its newline) of a `candump -l` log.
pub fn parse_line(line: &str) -> Result<CandumpRecord, CandumpParseError> {
    let mut fields = line.split_ascii_whitespace();
    let time = fields.next().ok_or_else(|| bad("empty line"))?;
    let interface = fields.next().ok_or_else(|| bad("no interface"))?;
    let frame = fields.next().ok_or_else(|| bad("no frame"))?;
    let time = time.strip_prefix('(').and_then(|t| t.strip_suffix(')')).ok_or_else(|| bad("no (time)"))?;
    let t_us = parse_seconds(time)?;
    Ok(CandumpRecord { t_us: Some(t_us), interface: interface.to_string(), frame: parse_frame(frame)? })
}

/// Parses a line of either format: a `candump -l` record (`ID#DATA`) or a
/// line of candump's console output.
pub fn parse_any_line(line: &str) -> Result<CandumpRecord, CandumpParseError> {
    if line.contains('#') { parse_line(line) } else { plain::parse_plain_line(line) }
}

fn parse_frame(text: &str) -> Result<CandumpFrame, CandumpParseError> {
    let (id_text, data_text) = text.split_once('#').ok_or_else(|| bad("no '#' in the frame"))?;
    let extended = match id_text.len() {
        3 => false,
        8 => true,
        _ => return Err(bad("the id is not 3 or 8 hex digits")),
    };
    let id = u32::from_str_radix(id_text, 16).map_err(|_| bad("the id is not hex"))?;
    if data_text.starts_with('#') || data_text.starts_with('R') || (extended && id & ERROR_FLAG != 0) {
        return Ok(CandumpFrame::Other);
    }
    if extended && id > 0x1FFF_FFFF {
        return Err(bad("the id has more than 29 bits"));
    }
    let data_text: String = data_text.chars().filter(|c| *c != '.').collect();
    if !data_text.len().is_multiple_of(2) || data_text.len() > 16 {
        return Err(bad("the data is not 0 to 8 hex bytes"));
    }
    let data = (0..data_text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&data_text[i..i + 2], 16))
        .collect::<Result<Vec<u8>, _>>()
        .map_err(|_| bad("the data is not hex"))?;
    Ok(CandumpFrame::Data { id, extended, data })
}

/// One line of a `candump -l` log for a data frame received at `t_us` (µs
/// since the Unix epoch) on `interface`, without the newline.
pub fn format_line(t_us: u64, interface: &str, id: u32, extended: bool, data: &[u8]) -> String {
    let id = if extended { format!("{id:08X}") } else { format!("{id:03X}") };
    let data: String = data.iter().map(|b| format!("{b:02X}")).collect();
    format!("({}.{:06}) {interface} {id}#{data}", t_us / 1_000_000, t_us % 1_000_000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_can_utils_examples_parse() {
        let r = parse_line("(1436509052.249713) vcan0 044#2A366C2BBA").unwrap();
        assert_eq!(r.t_us, Some(1_436_509_052_249_713));
        assert_eq!(r.interface, "vcan0");
        let data = vec![0x2A, 0x36, 0x6C, 0x2B, 0xBA];
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x44, extended: false, data });
        let r = parse_line("(0.000005) can1 18FF0001#").unwrap();
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x18FF_0001, extended: true, data: vec![] });
        assert_eq!(parse_line("(1.000000) can0 123#R").unwrap().frame, CandumpFrame::Other);
        assert_eq!(parse_line("(1.000000) can0 123##1AABB").unwrap().frame, CandumpFrame::Other);
        assert_eq!(
            parse_line("(1.000000) can0 20000080#0000000000000000").unwrap().frame,
            CandumpFrame::Other
        );
    }

    #[test]
    fn both_formats_parse_through_one_entry_point() {
        assert_eq!(parse_any_line("(1.000000) can0 201#0700").unwrap().t_us, Some(1_000_000));
        assert_eq!(parse_any_line("  can0  201   [2]  07 00").unwrap().t_us, None);
    }

    #[test]
    fn formatted_lines_parse_back() {
        let line = format_line(1_700_000_000_123_456, "can0", 0x710, false, &[0, 0x12, 0xAB]);
        assert_eq!(line, "(1700000000.123456) can0 710#0012AB");
        let r = parse_line(&line).unwrap();
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x710, extended: false, data: vec![0, 0x12, 0xAB] });
    }

    #[test]
    fn malformed_lines_say_why() {
        for line in [
            "",
            "garbage that is not candump",
            "1.000000 can0 123#00",
            "(1.5) can0 123#00",
            "(1.000000) can0",
            "(1.000000) can0 1234#00",
            "(1.000000) can0 123#0",
            "(1.000000) can0 123#001122334455667788",
            "(1.000000) can0 12G#00",
            "(1.000000) can0 123#ZZ",
            "(99999999999999999999.000000) can0 123#00",
        ] {
            assert!(parse_line(line).is_err(), "{line}");
        }
    }
}
