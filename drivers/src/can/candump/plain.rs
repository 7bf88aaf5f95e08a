//! candump's console output (can-utils `candump.c` with `lib.c`'s
//! `sprint_long_canframe`), one frame per line:
//!
//! ```text
//!   can0  201   [8]  01 02 03 04 05 06 07 08          candump can0
//!  (1436509052.249713)  can0  201   [2]  07 00        candump -t a can0
//!  (000.001021)  can0  12345678   [0]                 candump -t d (or -t z)
//!  (2015-07-10 08:17:32.249713)  can0  201   [1]  00  candump -t A: no time here
//!   can0  201   [8]  remote request                  remote frames
//! ```
//!
//! The id is 3 hex digits (standard) or 8 (extended; error frames carry the
//! error flag); `[n]` is the length (CAN FD frames print `[nn]` with two
//! digits and are not decoded here). Times in seconds come back as
//! microseconds, relative or absolute as candump printed them (the caller
//! knows which `-t` it used); a date (`-t A`) is not read: no time.

use super::record::{CandumpFrame, CandumpParseError, CandumpRecord, ERROR_FLAG, bad, parse_seconds};

/// Parses one line (without its newline) of candump's console output.
pub fn parse_plain_line(line: &str) -> Result<CandumpRecord, CandumpParseError> {
    let mut rest = line.trim_start();
    let mut t_us = None;
    if let Some(after) = rest.strip_prefix('(') {
        let (time, tail) = after.split_once(')').ok_or_else(|| bad("unclosed (time)"))?;
        // `-t A` prints a date and a time of day: kept as no time.
        if !time.contains(' ') {
            t_us = Some(parse_seconds(time)?);
        }
        rest = tail;
    }
    let mut fields = rest.split_ascii_whitespace();
    let interface = fields.next().ok_or_else(|| bad("no interface"))?;
    let id_text = fields.next().ok_or_else(|| bad("no id"))?;
    let len_text = fields.next().ok_or_else(|| bad("no [length]"))?;
    let extended = match id_text.len() {
        3 => false,
        8 => true,
        _ => return Err(bad("the id is not 3 or 8 hex digits")),
    };
    let id = u32::from_str_radix(id_text, 16).map_err(|_| bad("the id is not hex"))?;
    let len_digits =
        len_text.strip_prefix('[').and_then(|l| l.strip_suffix(']')).ok_or_else(|| bad("no [length]"))?;
    let len: usize = len_digits.parse().map_err(|_| bad("the length is not a number"))?;
    let interface = interface.to_string();
    let other = |interface| Ok(CandumpRecord { t_us, interface, frame: CandumpFrame::Other });
    if len_digits.len() > 1 || (extended && id & ERROR_FLAG != 0) {
        return other(interface); // CAN FD or an error frame
    }
    if extended && id > 0x1FFF_FFFF {
        return Err(bad("the id has more than 29 bits"));
    }
    let bytes: Vec<&str> = fields.collect();
    if bytes.first().is_some_and(|b| *b == "remote") {
        return other(interface);
    }
    if len > 8 || bytes.len() < len {
        return Err(bad("fewer data bytes than the [length] says"));
    }
    // candump -a appends the bytes as ASCII after them ('...'): ignored.
    let data = bytes[..len]
        .iter()
        .map(|b| if b.len() == 2 { u8::from_str_radix(b, 16).ok() } else { None })
        .collect::<Option<Vec<u8>>>()
        .ok_or_else(|| bad("the data is not hex bytes"))?;
    Ok(CandumpRecord { t_us, interface, frame: CandumpFrame::Data { id, extended, data } })
}

/// A line of candump's console output for a data frame, as `candump can0`
/// (no time) or `candump -t a can0` / `-t z` / `-t d` (`t_us` in
/// microseconds) prints it, without the newline.
pub fn format_plain_line(t_us: Option<u64>, interface: &str, id: u32, extended: bool, data: &[u8]) -> String {
    let time = t_us.map_or(String::new(), |t| format!("({:03}.{:06}) ", t / 1_000_000, t % 1_000_000));
    let id = if extended { format!("{id:08X}") } else { format!("{id:03X}") };
    let bytes: String = data.iter().map(|b| format!(" {b:02X}")).collect();
    format!(" {time} {interface}  {id}   [{}] {bytes}", data.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_console_formats_parse() {
        let r = parse_plain_line("  can0  201   [8]  01 02 03 04 05 06 07 08").unwrap();
        assert_eq!((r.t_us, r.interface.as_str()), (None, "can0"));
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x201, extended: false, data: (1..=8).collect() });
        let r = parse_plain_line(" (1436509052.249713)  can0  201   [2]  07 00").unwrap();
        assert_eq!(r.t_us, Some(1_436_509_052_249_713));
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x201, extended: false, data: vec![7, 0] });
        let r = parse_plain_line(" (000.001021)  vcan0  12345678   [0] ").unwrap();
        assert_eq!(r.t_us, Some(1021));
        assert_eq!(r.frame, CandumpFrame::Data { id: 0x1234_5678, extended: true, data: vec![] });
        let r = parse_plain_line(" (2015-07-10 08:17:32.249713)  can0  201   [1]  00").unwrap();
        assert_eq!((r.t_us, r.interface.as_str()), (None, "can0"));
        assert_eq!(parse_plain_line("  can0  201   [8]  remote request").unwrap().frame, CandumpFrame::Other);
        assert_eq!(
            parse_plain_line("  can0  20000004   [8]  00 04 00 00 00 00 00 00").unwrap().frame,
            CandumpFrame::Other
        );
        assert_eq!(parse_plain_line("  can0  201  [12]  00 00").unwrap().frame, CandumpFrame::Other);
        let line = format_plain_line(Some(1_021), "can0", 0x201, false, &[7, 0]);
        assert_eq!(line, " (000.001021)  can0  201   [2]  07 00");
        assert_eq!(parse_plain_line(&line).unwrap().t_us, Some(1021));
        assert_eq!(format_plain_line(None, "can0", 0x201, false, &[]), "  can0  201   [0] ");
    }

    #[test]
    fn malformed_console_lines_say_why() {
        for line in [
            "",
            "  can0",
            "  can0  201",
            "  can0  201   8  00",
            "  can0  2011   [1]  00",
            "  can0  201   [2]  00",
            "  can0  201   [1]  0",
            "  can0  201   [9]  00 00 00 00 00 00 00 00 00",
            "  can0  4FFFFFFF   [0]",
            " (1.5)  can0  201   [0]",
            " (1.000000  can0  201   [0]",
        ] {
            assert!(parse_plain_line(line).is_err(), "{line}");
        }
    }
}
