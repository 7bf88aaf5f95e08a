//! File-level helpers of the CSV readers ([`super::xela_csv`],
//! [`super::xela_psc`]): CSV tables with line numbers, exact headers, strict
//! field parsing, the `meta_data.csv.npy` string and the wall-clock times of
//! `meta_data.csv`. Every error is one line naming the file, the line and the
//! column.

use std::fs;
use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};

/// One CSV data row: its line number in the file (1-based, the header is
/// line 1) and its fields.
pub(crate) struct Row {
    /// Line number in the file (1-based).
    pub line: u64,
    /// The fields, as written.
    pub fields: csv::StringRecord,
}

/// A whole CSV file: its header and its data rows in file order.
pub(crate) struct Table {
    /// Column names of the first line.
    pub header: Vec<String>,
    /// Data rows, each with as many fields as the header (checked).
    pub rows: Vec<Row>,
}

/// Reads a comma-separated file with a header line; every row must have as
/// many fields as the header.
pub(crate) fn read_table(path: &Path) -> Result<Table> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_path(path)
        .with_context(|| format!("{}: cannot open", path.display()))?;
    let mut records = reader.records();
    let header = match records.next() {
        Some(record) => record.with_context(|| format!("{}: line 1", path.display()))?,
        None => bail!("{}: empty file (no header line)", path.display()),
    };
    let header: Vec<String> = header.iter().map(str::to_owned).collect();
    let mut rows = Vec::new();
    for record in records {
        let fields = record.with_context(|| format!("{}: malformed CSV", path.display()))?;
        let line = fields.position().map_or(0, csv::Position::line);
        if fields.len() != header.len() {
            bail!(
                "{}:{line}: expected {} fields as in the header, found {}",
                path.display(),
                header.len(),
                fields.len()
            );
        }
        rows.push(Row { line, fields });
    }
    Ok(Table { header, rows })
}

/// Fails unless the header is exactly `expected`, naming the first column
/// that differs.
pub(crate) fn check_header(path: &Path, header: &[String], expected: &[&str]) -> Result<()> {
    for (col, want) in expected.iter().enumerate() {
        match header.get(col) {
            Some(got) if got == want => {}
            Some(got) => bail!("{}:1: column {} is {got:?}, expected {want:?}", path.display(), col + 1),
            None => bail!("{}:1: missing column {} {want:?}", path.display(), col + 1),
        }
    }
    if header.len() > expected.len() {
        bail!(
            "{}:1: {} columns, expected {} (extra column {:?})",
            path.display(),
            header.len(),
            expected.len(),
            header[expected.len()]
        );
    }
    Ok(())
}

/// The data rows of a file with the expected header, each parsed by `row`;
/// a file without data rows is an error.
pub(crate) fn read_rows<T>(
    path: &Path,
    expected: &[&str],
    mut row: impl FnMut(&Path, &[String], &Row) -> Result<T>,
) -> Result<Vec<T>> {
    let table = read_table(path)?;
    check_header(path, &table.header, expected)?;
    if table.rows.is_empty() {
        bail!("{}: no data rows", path.display());
    }
    table.rows.iter().map(|r| row(path, &table.header, r)).collect()
}

/// The fields of a row as finite numbers (the row has `N` fields: checked by
/// the header).
pub(crate) fn numbers<const N: usize>(path: &Path, header: &[String], row: &Row) -> Result<[f64; N]> {
    let mut out = [0.0; N];
    for (col, (slot, value)) in out.iter_mut().zip(row.fields.iter()).enumerate() {
        *slot = parse_f64(At { path, line: row.line, col, name: &header[col] }, value)?;
    }
    Ok(out)
}

/// Where a field is, for error messages.
#[derive(Clone, Copy)]
pub(crate) struct At<'a> {
    /// The file.
    pub path: &'a Path,
    /// Line number (1-based).
    pub line: u64,
    /// Column index (0-based; messages print it 1-based).
    pub col: usize,
    /// Column name from the header.
    pub name: &'a str,
}

impl At<'_> {
    pub(crate) fn error(&self, what: &str, value: &str) -> anyhow::Error {
        anyhow!(
            "{}:{}: column {} ({}): {what}: {value:?}",
            self.path.display(),
            self.line,
            self.col + 1,
            self.name
        )
    }
}

/// Parses a finite number.
pub(crate) fn parse_f64(at: At<'_>, value: &str) -> Result<f64> {
    match value.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(at.error("not a finite number", value)),
        Err(_) => Err(at.error("not a number", value)),
    }
}

/// Parses a raw 16-bit count written as a float (`49198.0`): it must be a
/// whole number in 0..=65535.
pub(crate) fn parse_count(at: At<'_>, value: &str) -> Result<u16> {
    let v = parse_f64(at, value)?;
    if v.fract() != 0.0 || !(0.0..=f64::from(u16::MAX)).contains(&v) {
        return Err(at.error("not a whole 16-bit count", value));
    }
    Ok(v as u16)
}

/// Parses a `0`/`1` flag.
pub(crate) fn parse_flag(at: At<'_>, value: &str) -> Result<bool> {
    match value.trim() {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(at.error("not a 0/1 flag", value)),
    }
}

/// Parses `YYYY-MM-DD HH:MM:SS[.ffffff]` (Python's `str(datetime)`, no time
/// zone) into seconds since 1970-01-01 00:00:00 of the same clock.
pub(crate) fn parse_wall_time_s(at: At<'_>, value: &str) -> Result<f64> {
    wall_time_s(value.trim()).ok_or_else(|| at.error("not a YYYY-MM-DD HH:MM:SS.ffffff time", value))
}

fn wall_time_s(text: &str) -> Option<f64> {
    let (date, time) = text.split_once(' ')?;
    let mut ymd = date.split('-');
    let year: i64 = ymd.next()?.parse().ok()?;
    let month: i64 = ymd.next()?.parse().ok()?;
    let day: i64 = ymd.next()?.parse().ok()?;
    let mut hms = time.split(':');
    let hour: i64 = hms.next()?.parse().ok()?;
    let minute: i64 = hms.next()?.parse().ok()?;
    let second: f64 = hms.next()?.parse().ok()?;
    let valid = ymd.next().is_none()
        && hms.next().is_none()
        && (1..=12).contains(&month)
        && (1..=31).contains(&day)
        && (0..24).contains(&hour)
        && (0..60).contains(&minute)
        && (0.0..61.0).contains(&second);
    if !valid {
        return None;
    }
    let days = days_from_civil(year, month, day);
    Some((days * 86_400 + hour * 3600 + minute * 60) as f64 + second)
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's
/// `days_from_civil`).
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (month + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Reads a NumPy `.npy` file holding one unicode string (dtype `<U{n}`,
/// shape `()`), as `np.save(path, "text")` writes it.
pub(crate) fn read_npy_string(path: &Path) -> Result<String> {
    let bytes = fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    npy_string(&bytes).map_err(|why| anyhow!("{}: not a NumPy unicode scalar: {why}", path.display()))
}

fn npy_string(bytes: &[u8]) -> std::result::Result<String, String> {
    let magic = bytes.get(..6).ok_or("shorter than the magic string")?;
    if magic != b"\x93NUMPY" {
        return Err("bad magic string".into());
    }
    let major = *bytes.get(6).ok_or("no version")?;
    let (len, start) = match major {
        1 => (usize::from(u16::from_le_bytes([byte(bytes, 8)?, byte(bytes, 9)?])), 10),
        2 | 3 => {
            let raw = [byte(bytes, 8)?, byte(bytes, 9)?, byte(bytes, 10)?, byte(bytes, 11)?];
            (usize::try_from(u32::from_le_bytes(raw)).map_err(|e| e.to_string())?, 12)
        }
        v => return Err(format!("unknown format version {v}")),
    };
    let header = bytes.get(start..start + len).ok_or("header runs past the end")?;
    let header = std::str::from_utf8(header).map_err(|e| e.to_string())?;
    let chars = header
        .split_once("'<U")
        .and_then(|(_, rest)| rest.split_once('\''))
        .and_then(|(n, _)| n.parse::<usize>().ok())
        .ok_or("dtype is not '<U{n}'")?;
    if !header.contains("'shape': ()") {
        return Err("shape is not ()".into());
    }
    let body = &bytes[start + len..];
    if body.len() != 4 * chars {
        return Err(format!("{} data bytes for {chars} characters", body.len()));
    }
    body.chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .take_while(|&c| c != 0)
        .map(|c| char::from_u32(c).ok_or_else(|| format!("invalid code point {c:#x}")))
        .collect()
}

fn byte(bytes: &[u8], i: usize) -> std::result::Result<u8, String> {
    bytes.get(i).copied().ok_or_else(|| "header length runs past the end".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wall_time_is_seconds_since_1970() {
        assert_eq!(wall_time_s("1970-01-01 00:00:00"), Some(0.0));
        assert_eq!(wall_time_s("2000-03-01 00:00:01.5"), Some(951_868_801.5));
        let t = wall_time_s("2021-11-24 15:19:09.142171").unwrap();
        assert!((t - 1_637_767_149.142_171).abs() < 1e-6, "{t}");
        assert_eq!(wall_time_s("2021-13-24 15:19:09"), None);
        assert_eq!(wall_time_s("2021-11-24T15:19:09"), None);
    }

    #[test]
    fn npy_string_round_trips_numpy_layout() {
        let text = "/a/b.csv";
        let header = format!("{{'descr': '<U{}', 'fortran_order': False, 'shape': (), }}", text.len());
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&u16::try_from(header.len()).unwrap().to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        for c in text.chars() {
            bytes.extend_from_slice(&u32::from(c).to_le_bytes());
        }
        assert_eq!(npy_string(&bytes).unwrap(), text);
        assert!(npy_string(&bytes[..bytes.len() - 1]).is_err());
        assert!(npy_string(b"\x93NUMPX\x01\x00").is_err());
    }
}
