//! Parsers of object model files: XYZ point lists, Wavefront OBJ and PLY
//! (ASCII, binary little- and big-endian). Only geometry is read: vertex
//! positions and faces (polygons are split into triangle fans).

use nalgebra::Point3;

/// Geometry read from a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Parsed {
    /// Vertex positions.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles (vertex indices), empty for point clouds.
    pub triangles: Vec<[u32; 3]>,
}

/// XYZ: one point per line, `x y z` (more columns ignored), `#` comments.
pub fn xyz(text: &str) -> Result<Parsed, String> {
    let mut vertices = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or_default().trim();
        if line.is_empty() {
            continue;
        }
        let numbers: Vec<f64> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .take(3)
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", n + 1))?;
        let [x, y, z] = numbers[..] else {
            return Err(format!("line {}: expected x y z", n + 1));
        };
        vertices.push(Point3::new(x, y, z));
    }
    Ok(Parsed { vertices, triangles: Vec::new() })
}

/// Wavefront OBJ: `v x y z` and `f a b c ...` (indices 1-based or negative,
/// with optional `/vt/vn` parts).
pub fn obj(text: &str) -> Result<Parsed, String> {
    let mut parsed = Parsed::default();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f64> = words
                    .take(3)
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|e| format!("line {}: {e}", n + 1))?;
                let [x, y, z] = c[..] else {
                    return Err(format!("line {}: a vertex needs x y z", n + 1));
                };
                parsed.vertices.push(Point3::new(x, y, z));
            }
            Some("f") => {
                let count = parsed.vertices.len() as i64;
                let indices: Vec<u32> = words
                    .map(|w| {
                        let i: i64 = w
                            .split('/')
                            .next()
                            .unwrap_or_default()
                            .parse()
                            .map_err(|e| format!("line {}: {e}", n + 1))?;
                        let i = if i < 0 { count + i } else { i - 1 };
                        if i < 0 || i >= count {
                            return Err(format!("line {}: vertex index out of range", n + 1));
                        }
                        Ok(i as u32)
                    })
                    .collect::<Result<_, String>>()?;
                fan(&indices, &mut parsed.triangles);
            }
            _ => {}
        }
    }
    Ok(parsed)
}

/// Splits a polygon into a triangle fan.
fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        out.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

/// A property of a PLY element.
#[derive(Clone, Debug)]
enum Property {
    Scalar { name: String, kind: String },
    List { name: String, count: String, item: String },
}

/// PLY (`ascii`, `binary_little_endian`, `binary_big_endian`): the `x y z`
/// of `vertex` and the `vertex_indices` (or `vertex_index`) of `face`.
pub fn ply(bytes: &[u8]) -> Result<Parsed, String> {
    let end = find(bytes, b"end_header").ok_or("no end_header")?;
    let body_start = bytes[end..]
        .iter()
        .position(|b| *b == b'\n')
        .map(|p| end + p + 1)
        .ok_or("no data after the header")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| "the header is not text")?;
    let mut format = String::new();
    let mut elements: Vec<(String, usize, Vec<Property>)> = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", f, ..] => format = (*f).to_string(),
            ["element", name, count] => {
                elements.push(((*name).into(), count.parse().map_err(|_| "bad element count")?, Vec::new()))
            }
            ["property", "list", count, item, name] => {
                if let Some(e) = elements.last_mut() {
                    e.2.push(Property::List {
                        name: (*name).into(),
                        count: (*count).into(),
                        item: (*item).into(),
                    });
                }
            }
            ["property", kind, name] => {
                if let Some(e) = elements.last_mut() {
                    e.2.push(Property::Scalar { name: (*name).into(), kind: (*kind).into() });
                }
            }
            _ => {}
        }
    }
    let mut reader = match format.as_str() {
        "ascii" => Reader::Ascii(
            std::str::from_utf8(&bytes[body_start..])
                .map_err(|_| "ASCII body is not text")?
                .split_whitespace(),
        ),
        "binary_little_endian" => Reader::Binary { data: &bytes[body_start..], at: 0, little: true },
        "binary_big_endian" => Reader::Binary { data: &bytes[body_start..], at: 0, little: false },
        other => return Err(format!("unknown PLY format '{other}'")),
    };
    let mut parsed = Parsed::default();
    for (name, count, properties) in &elements {
        for _ in 0..*count {
            let mut xyz = [0.0; 3];
            let mut polygon = Vec::new();
            for p in properties {
                match p {
                    Property::Scalar { name: pname, kind } => {
                        let v = reader.number(kind)?;
                        if let Some(i) = ["x", "y", "z"].iter().position(|a| a == pname) {
                            xyz[i] = v;
                        }
                    }
                    Property::List { name: pname, count, item } => {
                        let n = reader.number(count)? as usize;
                        for _ in 0..n {
                            let v = reader.number(item)?;
                            if pname == "vertex_indices" || pname == "vertex_index" {
                                polygon.push(v as u32);
                            }
                        }
                    }
                }
            }
            if name == "vertex" {
                parsed.vertices.push(Point3::from(xyz));
            } else if name == "face" {
                fan(&polygon, &mut parsed.triangles);
            }
        }
    }
    let n = parsed.vertices.len() as u32;
    if parsed.triangles.iter().flatten().any(|i| *i >= n) {
        return Err("a face refers to a vertex that does not exist".into());
    }
    Ok(parsed)
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

enum Reader<'a> {
    Ascii(std::str::SplitWhitespace<'a>),
    Binary { data: &'a [u8], at: usize, little: bool },
}

impl Reader<'_> {
    fn number(&mut self, kind: &str) -> Result<f64, String> {
        match self {
            Reader::Ascii(words) => {
                words.next().ok_or("the data ends early")?.parse().map_err(|e| format!("{e}"))
            }
            Reader::Binary { data, at, little } => {
                let size = match kind {
                    "char" | "uchar" | "int8" | "uint8" => 1,
                    "short" | "ushort" | "int16" | "uint16" => 2,
                    "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
                    "double" | "float64" => 8,
                    other => return Err(format!("unknown PLY type '{other}'")),
                };
                let raw = data.get(*at..*at + size).ok_or("the data ends early")?;
                *at += size;
                let mut b = [0u8; 8];
                b[..size].copy_from_slice(raw);
                if !*little {
                    b[..size].reverse();
                }
                Ok(match kind {
                    "char" | "int8" => f64::from(b[0] as i8),
                    "uchar" | "uint8" => f64::from(b[0]),
                    "short" | "int16" => f64::from(i16::from_le_bytes([b[0], b[1]])),
                    "ushort" | "uint16" => f64::from(u16::from_le_bytes([b[0], b[1]])),
                    "int" | "int32" => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    "uint" | "uint32" => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    "float" | "float32" => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    _ => f64::from_le_bytes(b),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xyz_reads_points_and_refuses_junk() {
        let p = xyz("# model\n0.1 0.2 0.3\n\n1 2 3 0 0 1\n").unwrap();
        assert_eq!(p.vertices, vec![Point3::new(0.1, 0.2, 0.3), Point3::new(1.0, 2.0, 3.0)]);
        assert!(xyz("1 2\n").is_err());
        assert!(xyz("1 two 3\n").is_err());
    }

    #[test]
    fn obj_reads_triangles_and_quads() {
        let p = obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\nf -1 -2 -3\n").unwrap();
        assert_eq!(p.vertices.len(), 4);
        assert_eq!(p.triangles, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
        assert!(obj("v 0 0 0\nf 1 2 3\n").is_err());
    }

    #[test]
    fn ply_reads_ascii_and_binary() {
        let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                     element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let p = ply(ascii.as_bytes()).unwrap();
        assert_eq!(p.vertices[1], Point3::new(1.0, 0.0, 0.0));
        assert_eq!(p.triangles, vec![[0, 1, 2]]);
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
                        property double z\nproperty uchar red\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
            .to_vec();
        for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.5]] {
            for c in v {
                bin.extend(c.to_le_bytes());
            }
            bin.push(200);
        }
        bin.push(3);
        for i in [0u32, 1, 2] {
            bin.extend(i.to_le_bytes());
        }
        let p = ply(&bin).unwrap();
        assert_eq!(p.vertices[2], Point3::new(0.0, 2.0, 0.5));
        assert_eq!(p.triangles, vec![[0, 1, 2]]);
        assert!(ply(&bin[..bin.len() - 2]).is_err(), "truncated");
        assert!(ply(b"ply\nformat weird 1.0\nend_header\n").is_err());
    }
}
