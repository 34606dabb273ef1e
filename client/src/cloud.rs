//! Minimal PLY and PCD readers: the `x`, `y`, `z` of every vertex / point.
//!
//! PLY: `ascii` and `binary_little_endian`, vertex properties of any scalar
//! type (other elements must come after `vertex`). PCD: `ascii` and `binary`
//! (not `binary_compressed`), fields of size 1, 2, 4 or 8. Points with a
//! non-finite coordinate are kept (the server skips them).

use std::path::Path;

use crate::{Error, Result};

fn bad(path: &Path, reason: impl Into<String>) -> Error {
    Error::Input {
        file: path.display().to_string(),
        reason: reason.into(),
    }
}

/// Reads the points of a `.ply` or `.pcd` file (by extension).
pub fn read_points(path: &Path) -> Result<Vec<[f32; 3]>> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, e.to_string()))?;
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("ply") => parse_ply(&bytes).map_err(|e| bad(path, e)),
        Some("pcd") => parse_pcd(&bytes).map_err(|e| bad(path, e)),
        _ => Err(bad(path, "expected a .ply or .pcd file")),
    }
}

/// Splits off the text header ending with the line `end_marker`.
fn header<'a>(bytes: &'a [u8], end_marker: &str) -> Result<(Vec<String>, &'a [u8]), String> {
    let mut lines = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let end = bytes[at..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| at + p);
        let line = String::from_utf8_lossy(&bytes[at..end]).trim().to_owned();
        at = (end + 1).min(bytes.len());
        let done = line.split_whitespace().next() == Some(end_marker);
        lines.push(line);
        if done {
            return Ok((lines, &bytes[at..]));
        }
        if lines.len() > 10_000 {
            break;
        }
    }
    Err(format!("no `{end_marker}` line: not a valid header"))
}

#[derive(Debug, Clone, Copy)]
enum Scalar {
    I(usize),
    U(usize),
    F(usize),
}

impl Scalar {
    fn size(self) -> usize {
        match self {
            Self::I(n) | Self::U(n) | Self::F(n) => n,
        }
    }

    fn read_le(self, b: &[u8]) -> f32 {
        match (self, b.len()) {
            (Self::F(4), 4) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            (Self::F(8), 8) => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32,
            (Self::I(1), 1) => f32::from(b[0] as i8),
            (Self::U(1), 1) => f32::from(b[0]),
            (Self::I(2), 2) => f32::from(i16::from_le_bytes([b[0], b[1]])),
            (Self::U(2), 2) => f32::from(u16::from_le_bytes([b[0], b[1]])),
            (Self::I(4), 4) => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            (Self::U(4), 4) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            _ => f32::NAN,
        }
    }
}

fn ply_scalar(name: &str) -> Option<Scalar> {
    Some(match name {
        "char" | "int8" => Scalar::I(1),
        "uchar" | "uint8" => Scalar::U(1),
        "short" | "int16" => Scalar::I(2),
        "ushort" | "uint16" => Scalar::U(2),
        "int" | "int32" => Scalar::I(4),
        "uint" | "uint32" => Scalar::U(4),
        "float" | "float32" => Scalar::F(4),
        "double" | "float64" => Scalar::F(8),
        _ => return None,
    })
}

/// Points of a table of `count` records with `fields` (name, type), little-endian
/// binary or whitespace-separated text.
fn records(
    body: &[u8],
    count: usize,
    fields: &[(String, Scalar)],
    binary: bool,
) -> Result<Vec<[f32; 3]>, String> {
    let index = |axis: &str| {
        fields
            .iter()
            .position(|(n, _)| n == axis)
            .ok_or_else(|| format!("no `{axis}` field"))
    };
    let (ix, iy, iz) = (index("x")?, index("y")?, index("z")?);
    if let Some((name, _)) = fields.iter().find(|(_, s)| ![1, 2, 4, 8].contains(&s.size())) {
        return Err(format!("field {name}: size must be 1, 2, 4 or 8 bytes"));
    }
    // The header's count is a claim: reserve only what the body can hold
    // (a binary record takes `stride` bytes, a text one at least 6: "0 0 0\n").
    let stride: usize = fields.iter().map(|(_, s)| s.size()).sum();
    let fits = body.len() / if binary { stride } else { 6 };
    let mut points = Vec::with_capacity(count.min(fits));
    if binary {
        let offsets: Vec<usize> = fields
            .iter()
            .scan(0, |acc, (_, s)| {
                let at = *acc;
                *acc += s.size();
                Some(at)
            })
            .collect();
        let needed = stride.saturating_mul(count);
        if body.len() < needed {
            return Err(format!(
                "{count} records of {stride} bytes need more than the {} bytes the file has",
                body.len()
            ));
        }
        for record in body.chunks_exact(stride).take(count) {
            let get = |i: usize| {
                fields[i]
                    .1
                    .read_le(&record[offsets[i]..offsets[i] + fields[i].1.size()])
            };
            points.push([get(ix), get(iy), get(iz)]);
        }
    } else {
        let text = String::from_utf8_lossy(body);
        for (n, line) in text
            .lines()
            .filter(|l| !l.trim().is_empty())
            .take(count)
            .enumerate()
        {
            let values: Vec<&str> = line.split_whitespace().collect();
            let get = |i: usize| -> Result<f32, String> {
                values
                    .get(i)
                    .and_then(|v| v.parse::<f32>().ok())
                    .ok_or_else(|| format!("record {n}: field {i} is missing or not a number"))
            };
            points.push([get(ix)?, get(iy)?, get(iz)?]);
        }
        if points.len() < count {
            return Err(format!("{count} records declared, {} found", points.len()));
        }
    }
    Ok(points)
}

/// The vertices of a PLY file's bytes.
pub fn parse_ply(bytes: &[u8]) -> Result<Vec<[f32; 3]>, String> {
    if !bytes.starts_with(b"ply") {
        return Err("not a PLY file (no `ply` magic)".into());
    }
    let (lines, body) = header(bytes, "end_header")?;
    let mut binary = None;
    let mut count = None;
    let mut fields = Vec::new();
    let mut in_vertex = false;
    for line in &lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "ascii", ..] => binary = Some(false),
            ["format", "binary_little_endian", ..] => binary = Some(true),
            ["format", other, ..] => return Err(format!("PLY format {other} is not supported")),
            ["element", "vertex", n] => {
                count = Some(
                    n.parse::<usize>()
                        .map_err(|e| format!("vertex count {n:?}: {e}"))?,
                );
                in_vertex = true;
            }
            ["element", ..] => {
                if count.is_none() {
                    return Err("the `vertex` element must come first".into());
                }
                in_vertex = false;
            }
            ["property", "list", ..] if in_vertex => {
                return Err("list properties on vertices are not supported".into());
            }
            ["property", kind, name] if in_vertex => {
                let scalar = ply_scalar(kind).ok_or_else(|| format!("property type {kind:?}"))?;
                fields.push(((*name).to_owned(), scalar));
            }
            _ => {}
        }
    }
    let binary = binary.ok_or("no `format` line")?;
    let count = count.ok_or("no `element vertex` line")?;
    records(body, count, &fields, binary)
}

/// Most values one PCD field may hold (`COUNT`; descriptors such as VFH
/// hold 308).
const MAX_FIELD_COUNT: usize = 1024;

/// The points of a PCD file's bytes.
pub fn parse_pcd(bytes: &[u8]) -> Result<Vec<[f32; 3]>, String> {
    let (lines, body) = header(bytes, "DATA")?;
    let mut names: Vec<String> = Vec::new();
    let mut sizes: Vec<usize> = Vec::new();
    let mut types: Vec<char> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    let mut points = None;
    let mut binary = None;
    for line in &lines {
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or("");
        let rest: Vec<&str> = words.collect();
        match key {
            "FIELDS" => names = rest.iter().map(|s| (*s).to_owned()).collect(),
            "SIZE" => sizes = rest.iter().filter_map(|s| s.parse().ok()).collect(),
            "TYPE" => types = rest.iter().filter_map(|s| s.chars().next()).collect(),
            "COUNT" => counts = rest.iter().filter_map(|s| s.parse().ok()).collect(),
            "POINTS" => points = rest.first().and_then(|s| s.parse::<usize>().ok()),
            "DATA" => {
                binary = match rest.first().copied() {
                    Some("ascii") => Some(false),
                    Some("binary") => Some(true),
                    other => return Err(format!("PCD DATA {other:?} is not supported")),
                }
            }
            _ => {}
        }
    }
    if sizes.len() != names.len() || types.len() != names.len() {
        return Err("FIELDS, SIZE and TYPE disagree in length".into());
    }
    if counts.is_empty() {
        counts = vec![1; names.len()];
    }
    let mut fields = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let scalar = match types[i] {
            'F' => Scalar::F(sizes[i]),
            'I' => Scalar::I(sizes[i]),
            'U' => Scalar::U(sizes[i]),
            t => return Err(format!("field {name}: TYPE {t:?}")),
        };
        let count = counts.get(i).copied().unwrap_or(1);
        if count == 0 || count > MAX_FIELD_COUNT {
            return Err(format!(
                "field {name}: COUNT {count} is not in 1..={MAX_FIELD_COUNT}"
            ));
        }
        for k in 0..count {
            let label = if k == 0 {
                name.clone()
            } else {
                format!("{name}#{k}")
            };
            fields.push((label, scalar));
        }
    }
    let count = points.ok_or("no POINTS line")?;
    records(body, count, &fields, binary.ok_or("no DATA line")?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_ascii_and_binary_agree() {
        let ascii = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nend_header\n1 2 3 255\n4 5 6 0\n";
        assert_eq!(parse_ply(ascii).unwrap(), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty uchar red\nproperty float x\nproperty float y\nproperty double z\nend_header\n".to_vec();
        for (r, p) in [(9u8, [1.0f32, 2.0, 3.0]), (7, [4.0, 5.0, 6.0])] {
            binary.push(r);
            binary.extend(p[0].to_le_bytes());
            binary.extend(p[1].to_le_bytes());
            binary.extend(f64::from(p[2]).to_le_bytes());
        }
        assert_eq!(
            parse_ply(&binary).unwrap(),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
        assert!(
            parse_ply(&binary[..binary.len() - 3])
                .unwrap_err()
                .contains("need")
        );
    }

    /// Headers that claim more than the body holds, found by fuzzing (`fuzz/`,
    /// target `client_files`) or written after what it found.
    #[test]
    fn header_claims_are_errors_not_allocations() {
        let huge_count: &[u8] = include_bytes!("../../fuzz/regressions/client_files/pcd-huge-count.pcd");
        assert!(parse_pcd(huge_count).is_err());
        let count =
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 4000000000\nPOINTS 1\nDATA ascii\n1 2 3\n";
        assert!(parse_pcd(count).unwrap_err().contains("COUNT"));
        let zero_size = b"FIELDS x y z\nSIZE 0 0 0\nTYPE F F F\nPOINTS 1\nDATA binary\n";
        assert!(parse_pcd(zero_size).unwrap_err().contains("size"));
        let overflow = b"FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nPOINTS 18446744073709551615\nDATA binary\n";
        assert!(parse_pcd(overflow).unwrap_err().contains("need more"));
        let ply = b"ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
        assert!(parse_ply(ply).unwrap_err().contains("declared"));
    }

    #[test]
    fn pcd_ascii_and_binary() {
        let ascii = b"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
        assert_eq!(parse_pcd(ascii).unwrap(), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let mut binary = b"VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nPOINTS 1\nDATA binary\n".to_vec();
        for v in [0.5f32, -1.0, 2.0] {
            binary.extend(v.to_le_bytes());
        }
        binary.extend(7u32.to_le_bytes());
        assert_eq!(parse_pcd(&binary).unwrap(), vec![[0.5, -1.0, 2.0]]);
        let compressed = b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n";
        assert!(parse_pcd(compressed).unwrap_err().contains("binary_compressed"));
    }
}
