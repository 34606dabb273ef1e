//! User meshes as scene objects: Wavefront OBJ and STL (binary or ASCII)
//! files, decomposed into convex parts for physics (parry's V-HACD).
//!
//! Conventions: coordinates in metres times `scale` (0.001 for a file in
//! millimetres), z up as the file has it. The object frame puts the origin
//! at the centre of the bottom of the mesh's bounding box, as the procedural
//! objects have it. The camera and the physics both see the convex parts
//! (the same geometry for both); a concavity narrower than V-HACD's voxels
//! (1/64 of the longest side) is filled.
//!
//! Read: OBJ `v` and `f` statements (`f` indices may be `v`, `v/vt`,
//! `v//vn` or `v/vt/vn`, negative = relative; polygons are split into
//! fans); everything else in an OBJ is ignored. STL: binary when the size
//! matches the triangle count in the header, else ASCII `vertex` lines.
//! Every failure names the file and, for parse errors, the line.

use std::collections::HashMap;
use std::path::Path;

use parry3d::math::{Pose, Vector};
use parry3d::shape::SharedShape;
use parry3d::transformation::vhacd::{VHACD, VHACDParameters};

use crate::error::{Error, Result};
use crate::objects::{Family, ObjectModel};

/// A triangle mesh as read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Vertices (file units).
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// Longest side a mesh object may have (m): larger is most likely a file in
/// millimetres read as metres.
pub const MAX_SIDE_M: f32 = 0.6;

/// Most convex parts kept per mesh.
pub const MAX_PARTS: u32 = 24;

fn file_error(path: &Path, reason: impl Into<String>) -> Error {
    Error::File {
        path: path.display().to_string(),
        reason: reason.into(),
    }
}

/// Reads `path` (`.obj` or `.stl`, any case).
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let bytes = std::fs::read(path).map_err(|e| file_error(path, e.to_string()))?;
    let mesh = match ext.as_str() {
        "obj" => parse_obj(&bytes),
        "stl" => parse_stl(&bytes),
        _ => Err(format!("unknown mesh format {ext:?}: expected .obj or .stl")),
    }
    .map_err(|reason| file_error(path, reason))?;
    if mesh.triangles.is_empty() {
        return Err(file_error(path, "no triangles"));
    }
    Ok(mesh)
}

fn parse_floats<'a>(
    mut words: impl Iterator<Item = &'a str>,
    line: usize,
) -> std::result::Result<[f32; 3], String> {
    let mut out = [0.0f32; 3];
    for v in &mut out {
        let word = words
            .next()
            .ok_or_else(|| format!("line {line}: a vertex needs 3 coordinates"))?;
        *v = word
            .parse()
            .map_err(|_| format!("line {line}: {word:?} is not a number"))?;
        if !v.is_finite() {
            return Err(format!("line {line}: non-finite coordinate {word:?}"));
        }
    }
    Ok(out)
}

/// Parses the `v` and `f` statements of a Wavefront OBJ file.
pub fn parse_obj(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8 text: {e}"))?;
    let mut mesh = Mesh {
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let mut words = raw.split_whitespace();
        match words.next() {
            Some("v") => mesh.vertices.push(parse_floats(words, line)?),
            Some("f") => {
                let mut face = Vec::new();
                for word in words {
                    let first = word.split('/').next().unwrap_or_default();
                    let i: i64 = first
                        .parse()
                        .map_err(|_| format!("line {line}: bad face index {word:?}"))?;
                    let count = mesh.vertices.len() as i64;
                    let index = match i {
                        i if i > 0 && i <= count => i - 1,
                        i if i < 0 && -i <= count => count + i,
                        _ => {
                            return Err(format!(
                                "line {line}: face index {i} out of range ({count} vertices so far)"
                            ));
                        }
                    };
                    face.push(index as u32);
                }
                if face.len() < 3 {
                    return Err(format!("line {line}: a face needs at least 3 vertices"));
                }
                for k in 1..face.len() - 1 {
                    mesh.triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

/// Parses a binary or ASCII STL file; identical vertices are merged.
pub fn parse_stl(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let mut weld = Weld::default();
    let binary_count = bytes
        .get(80..84)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    match binary_count {
        Some(n) if n.checked_mul(50).and_then(|b| b.checked_add(84)) == Some(bytes.len()) => {
            for t in 0..n {
                let record = &bytes[84 + 50 * t..][..50];
                let mut corner = [0u32; 3];
                for (k, c) in corner.iter_mut().enumerate() {
                    let mut p = [0.0f32; 3];
                    for (a, v) in p.iter_mut().enumerate() {
                        let at = 12 + 12 * k + 4 * a;
                        *v = f32::from_le_bytes([record[at], record[at + 1], record[at + 2], record[at + 3]]);
                    }
                    if p.iter().any(|v| !v.is_finite()) {
                        return Err(format!("triangle {t}: non-finite coordinate"));
                    }
                    *c = weld.index(p);
                }
                weld.triangles.push(corner);
            }
        }
        _ => {
            let text = std::str::from_utf8(bytes).map_err(|_| {
                "neither a binary STL (size does not match its triangle count) nor ASCII".to_owned()
            })?;
            if !text.trim_start().starts_with("solid") {
                return Err(
                    "neither a binary STL (size does not match its triangle count) nor ASCII (no `solid`)"
                        .into(),
                );
            }
            let mut corners = Vec::new();
            for (n, raw) in text.lines().enumerate() {
                let mut words = raw.split_whitespace();
                if words.next() == Some("vertex") {
                    corners.push(weld.index(parse_floats(words, n + 1)?));
                    if corners.len() == 3 {
                        weld.triangles.push([corners[0], corners[1], corners[2]]);
                        corners.clear();
                    }
                }
            }
            if !corners.is_empty() {
                return Err(format!(
                    "{} vertices left over: not a whole triangle",
                    corners.len()
                ));
            }
        }
    }
    Ok(Mesh {
        vertices: weld.vertices,
        triangles: weld.triangles,
    })
}

#[derive(Default)]
struct Weld {
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    seen: HashMap<[u32; 3], u32>,
}

impl Weld {
    fn index(&mut self, p: [f32; 3]) -> u32 {
        let key = p.map(|v| (v + 0.0).to_bits()); // + 0.0 makes -0 and 0 one key
        let next = self.vertices.len() as u32;
        *self.seen.entry(key).or_insert_with(|| {
            self.vertices.push(p);
            next
        })
    }
}

/// The object made of `mesh` scaled by `scale`: convex parts in the object
/// frame (origin at the bottom centre), mass at the household density.
/// `name` names it in errors and reports.
pub fn object_from_mesh(mesh: &Mesh, scale: f32, name: &str) -> Result<ObjectModel> {
    let fail = |reason: String| Error::Shape(format!("{name}: {reason}"));
    if !(scale.is_finite() && scale > 0.0) {
        return Err(fail(format!("scale {scale} must be positive")));
    }
    let count = mesh.vertices.len() as u32;
    if let Some(t) = mesh.triangles.iter().find(|t| t.iter().any(|&i| i >= count)) {
        return Err(fail(format!("triangle {t:?} indexes past the {count} vertices")));
    }
    let (open, shared) = edge_defects(&mesh.triangles);
    if open + shared > 0 {
        return Err(fail(format!(
            "not a closed surface: {open} edges border one triangle, {shared} border more than two \
             (a solid's every edge borders exactly two)"
        )));
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &mesh.vertices {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] * scale);
            hi[a] = hi[a].max(p[a] * scale);
        }
    }
    let size = [0, 1, 2].map(|a| hi[a] - lo[a]);
    let longest = size.iter().copied().fold(0.0f32, f32::max);
    if longest > MAX_SIDE_M {
        return Err(fail(format!(
            "{longest:.3} m across after scaling by {scale}: too large for a table-top object \
             (a file in millimetres needs --mesh-scale 0.001)"
        )));
    }
    if size.iter().any(|&s| s < 0.005) {
        return Err(fail(format!(
            "flat: {:.1} x {:.1} x {:.1} mm after scaling by {scale}",
            size[0] * 1e3,
            size[1] * 1e3,
            size[2] * 1e3
        )));
    }
    let shortest = size.iter().copied().fold(f32::INFINITY, f32::min);
    if shortest > 0.14 {
        return Err(fail(format!(
            "{shortest:.3} m across its narrowest side: wider than the 2F-140's 0.14 m stroke"
        )));
    }
    let origin = Vector::new((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, lo[2]);
    let vertices: Vec<Vector> = mesh
        .vertices
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]) * scale - origin)
        .collect();
    let params = VHACDParameters {
        max_convex_hulls: MAX_PARTS,
        ..VHACDParameters::default()
    };
    let decomposition = VHACD::decompose(&params, &vertices, &mesh.triangles, true);
    let parts: Vec<(Pose, SharedShape)> = decomposition
        .compute_exact_convex_hulls(&vertices, &mesh.triangles)
        .into_iter()
        .filter_map(|(points, _)| SharedShape::convex_hull(&points))
        .map(|hull| (Pose::IDENTITY, hull))
        .collect();
    if parts.is_empty() {
        return Err(fail(
            "no convex part with volume (an open or degenerate mesh?)".into(),
        ));
    }
    let mut model = ObjectModel::from_parts(Family::Mesh, parts);
    model.name = name.to_owned();
    Ok(model)
}

/// Edges (undirected) that border one triangle, and edges that border more
/// than two: both zero for a closed 2-manifold surface.
fn edge_defects(triangles: &[[u32; 3]]) -> (usize, usize) {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let open = count.values().filter(|&&n| n == 1).count();
    let shared = count.values().filter(|&&n| n > 2).count();
    (open, shared)
}

/// Reads and decomposes every file of `paths` (see [`read_mesh`] and
/// [`object_from_mesh`]); objects are named after their file stems.
pub fn load_meshes(paths: &[impl AsRef<Path>], scale: f32) -> Result<Vec<ObjectModel>> {
    paths
        .iter()
        .map(|path| {
            let path = path.as_ref();
            let name = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("mesh")
                .to_owned();
            object_from_mesh(&read_mesh(path)?, scale, &name)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use parry3d::query::Ray;

    use super::*;

    /// A U channel lying along y: 10 cm wide, 6 cm tall, a 4 cm wide slot
    /// from z = 2 cm up, 8 cm long. Concave: the slot is open at the top.
    fn u_channel_obj() -> String {
        // Cross-section in x-z (counter-clockwise), extruded along y.
        let outline = [
            (-0.05, 0.0),
            (0.05, 0.0),
            (0.05, 0.06),
            (0.02, 0.06),
            (0.02, 0.02),
            (-0.02, 0.02),
            (-0.02, 0.06),
            (-0.05, 0.06),
        ];
        let mut obj = String::from("# U channel\n");
        for y in [-0.04, 0.04] {
            for (x, z) in outline {
                obj += &format!("v {x} {y} {z}\n");
            }
        }
        // End caps as three convex quads each (the outline is not convex).
        for (base, flip) in [(1, true), (9, false)] {
            for q in [[0, 1, 4, 5], [0, 5, 6, 7], [1, 2, 3, 4]] {
                let mut q = q.map(|i| i + base);
                if flip {
                    q.reverse();
                }
                obj += &format!("f {} {} {} {}\n", q[0], q[1], q[2], q[3]);
            }
        }
        for i in 0..8 {
            let j = (i + 1) % 8;
            obj += &format!("f {}/1/1 {}//2 {} {}\n", i + 1, j + 1, j + 9, i + 9);
        }
        obj
    }

    fn box_stl_ascii(h: [f32; 3]) -> String {
        let c = |i: usize| {
            [
                if i & 1 == 0 { -h[0] } else { h[0] },
                if i & 2 == 0 { -h[1] } else { h[1] },
                if i & 4 == 0 { 0.0 } else { 2.0 * h[2] },
            ]
        };
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let mut s = String::from("solid box\n");
        for q in quads {
            for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                s += "facet normal 0 0 0\nouter loop\n";
                for i in t {
                    let p = c(i);
                    s += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
                }
                s += "endloop\nendfacet\n";
            }
        }
        s + "endsolid box\n"
    }

    fn binary_stl(mesh: &Mesh) -> Vec<u8> {
        let mut out = vec![0u8; 80];
        out.extend((mesh.triangles.len() as u32).to_le_bytes());
        for t in &mesh.triangles {
            out.extend([0u8; 12]);
            for &i in t {
                for v in mesh.vertices[i as usize] {
                    out.extend(v.to_le_bytes());
                }
            }
            out.extend([0u8; 2]);
        }
        out
    }

    #[test]
    fn a_concave_obj_keeps_its_slot_after_decomposition() {
        let mesh = parse_obj(u_channel_obj().as_bytes()).unwrap();
        assert_eq!((mesh.vertices.len(), mesh.triangles.len()), (16, 28));
        let model = object_from_mesh(&mesh, 1.0, "u_channel").unwrap();
        assert!(model.parts.len() >= 2, "one convex part cannot hold a slot");
        assert_eq!(model.name, "u_channel");
        let (lo, hi) = (model.aabb.mins, model.aabb.maxs);
        for (got, want) in [
            (lo.x, -0.05),
            (hi.x, 0.05),
            (lo.z, 0.0),
            (hi.z, 0.06),
            (hi.y, 0.04),
        ] {
            assert!((got - want).abs() < 2e-3, "bounds {lo:?} {hi:?}");
        }
        // Straight down into the slot: the floor of the slot at 2 cm, not the hull's top at 6 cm.
        let down = Ray::new(Vector::new(0.0, 0.0, 0.2), Vector::new(0.0, 0.0, -1.0));
        let toi = model.shape.cast_local_ray(&down, 1.0, true).unwrap();
        assert!(
            (0.2 - toi - 0.02).abs() < 0.004,
            "the ray stopped at z = {}",
            0.2 - toi
        );
        // Down onto a wall: its top at 6 cm.
        let wall = Ray::new(Vector::new(0.035, 0.0, 0.2), Vector::new(0.0, 0.0, -1.0));
        let toi = model.shape.cast_local_ray(&wall, 1.0, true).unwrap();
        assert!(
            (0.2 - toi - 0.06).abs() < 0.004,
            "the ray stopped at z = {}",
            0.2 - toi
        );
        // Volume near the solid's 0.1*0.06*0.08 - 0.04*0.04*0.08 = 3.52e-4 m^3.
        let volume: f32 = model
            .parts
            .iter()
            .map(|(_, s)| s.mass_properties(1.0).mass())
            .sum();
        assert!((volume - 3.52e-4).abs() < 0.6e-4, "volume {volume}");
    }

    #[test]
    fn ascii_and_binary_stl_read_the_same_box() {
        let ascii = parse_stl(box_stl_ascii([0.03, 0.05, 0.04]).as_bytes()).unwrap();
        assert_eq!((ascii.vertices.len(), ascii.triangles.len()), (8, 12));
        let binary = parse_stl(&binary_stl(&ascii)).unwrap();
        assert_eq!(binary, ascii);
        let model = object_from_mesh(&binary, 1.0, "box").unwrap();
        let size = model.aabb.maxs - model.aabb.mins;
        assert!(
            (size - Vector::new(0.06, 0.1, 0.08)).abs().max_element() < 1e-3,
            "{size:?}"
        );
        assert!((model.mass_kg - 0.06 * 0.1 * 0.08 * 400.0).abs() < 0.02);
    }

    #[test]
    fn bad_meshes_are_refused_with_the_reason() {
        let cases: [(&[u8], &str, &str); 8] = [
            (
                b"v 0 0 0\nv 1 0 0\nf 1 2 3\n",
                "obj",
                "line 3: face index 3 out of range",
            ),
            (b"v 0 0 zero\n", "obj", "line 1: \"zero\" is not a number"),
            (b"v 0 0 NaN\n", "obj", "non-finite"),
            (b"v 0 0 0\nv 1 0 0\nf 1 2\n", "obj", "at least 3 vertices"),
            (
                b"solid x\nvertex 0 0 0\nvertex 1 0 0\n",
                "stl",
                "2 vertices left over",
            ),
            (b"\x00\x01garbage", "stl", "neither a binary STL"),
            (b"# only a comment\n", "obj", "no triangles"),
            (b"v 0 0 0\n", "ply", "expected .obj or .stl"),
        ];
        let dir = std::env::temp_dir().join(format!("mvgrasp-mesh-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (k, (bytes, ext, why)) in cases.iter().enumerate() {
            let path = dir.join(format!("bad{k}.{ext}"));
            std::fs::write(&path, bytes).unwrap();
            let err = read_mesh(&path).unwrap_err().to_string();
            assert!(
                err.contains(why) && err.contains(&format!("bad{k}")),
                "case {k}: {err}"
            );
        }
        let missing = read_mesh(&dir.join("missing.obj")).unwrap_err().to_string();
        assert!(missing.contains("missing.obj"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();

        let boxy = parse_stl(box_stl_ascii([0.03, 0.05, 0.04]).as_bytes()).unwrap();
        for (scale, why) in [
            (1000.0, "--mesh-scale 0.001"),
            (0.0, "must be positive"),
            (0.05, "flat"),
            (4.0, "wider than the 2F-140"),
        ] {
            let err = object_from_mesh(&boxy, scale, "boxy").unwrap_err().to_string();
            assert!(err.contains(why) && err.contains("boxy"), "scale {scale}: {err}");
        }
        // A box with its lid missing: open.
        let mut open = boxy.clone();
        let lid: Vec<usize> = (0..open.triangles.len())
            .filter(|&t| {
                open.triangles[t]
                    .iter()
                    .all(|&i| open.vertices[i as usize][2] > 0.0)
            })
            .collect();
        assert_eq!(lid.len(), 2);
        open.triangles
            .retain(|t| !t.iter().all(|&i| open.vertices[i as usize][2] > 0.0));
        let err = object_from_mesh(&open, 1.0, "open_box").unwrap_err().to_string();
        assert!(
            err.contains("not a closed surface: 4 edges border one triangle"),
            "{err}"
        );
        // A fin glued to one edge of the box: that edge borders three triangles.
        let mut finned = boxy.clone();
        finned.vertices.push([0.0, 0.2, 0.0]);
        let [a, b, _] = finned.triangles[0];
        finned.triangles.push([a, b, finned.vertices.len() as u32 - 1]);
        let err = object_from_mesh(&finned, 1.0, "finned").unwrap_err().to_string();
        assert!(err.contains("more than two"), "{err}");
    }
}
