//! A minimal Wavefront OBJ reader for collider meshes: `v` positions and `f` faces (polygons
//! are fan-triangulated, negative indices resolved). Everything else is ignored. It exists so
//! that benchmarks, tools and fuzzers can load a collider without an engine; the Bevy plugin
//! loads OBJ files through `bevy_obj` instead.

use core::fmt;

/// A triangle mesh read from OBJ text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangle-list indices into `positions`.
    pub indices: Vec<u32>,
}

impl ObjMesh {
    /// The mesh as the borrowed view the collider builder takes.
    pub fn as_mesh_ref(&self) -> crate::MeshRef<'_> {
        crate::MeshRef { positions: &self.positions, indices: Some(&self.indices) }
    }
}

/// Why OBJ text could not be read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong on that line.
    pub reason: &'static str,
}

impl fmt::Display for ObjError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "OBJ line {}: {}", self.line, self.reason)
    }
}

impl std::error::Error for ObjError {}

/// Parses OBJ text. Index validity against the vertex count is left to the collider builder,
/// except that indices must be non-zero integers that resolve to a non-negative position. A
/// UTF-8 byte-order mark at the start (as some Windows tools write) is skipped.
pub fn parse_obj(text: &str) -> Result<ObjMesh, ObjError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut mesh = ObjMesh::default();
    let mut face = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let line_no = number + 1;
        let err = |reason| ObjError { line: line_no, reason };
        let mut parts = line.split_whitespace();
        match parts.next() {
            Some("v") => {
                let mut p = [0.0f32; 3];
                for c in &mut p {
                    *c =
                        parts.next().and_then(|s| s.parse().ok()).ok_or_else(|| err("a vertex needs three numbers"))?;
                }
                mesh.positions.push(p);
            }
            Some("f") => {
                face.clear();
                for corner in parts {
                    let raw: i64 = corner
                        .split('/')
                        .next()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| err("a face corner must start with a vertex index"))?;
                    let resolved = match raw {
                        0 => return Err(err("OBJ indices start at 1; 0 is not an index")),
                        r if r > 0 => r - 1,
                        r => mesh.positions.len() as i64 + r,
                    };
                    let index = u32::try_from(resolved).map_err(|_| err("a face index is out of range"))?;
                    face.push(index);
                }
                if face.len() < 3 {
                    return Err(err("a face needs at least three corners"));
                }
                for k in 1..face.len() - 1 {
                    mesh.indices.extend_from_slice(&[face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_positions_and_triangulates() {
        let m = parse_obj("# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 -1//1\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.indices, vec![0, 1, 2, 0, 2, 3]);
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let marked = format!("\u{feff}{plain}");
        assert_eq!(parse_obj(&marked).unwrap(), parse_obj(plain).unwrap());
        assert_eq!(parse_obj(&marked).unwrap().positions.len(), 3);
    }

    #[test]
    fn reports_bad_lines() {
        assert_eq!(parse_obj("v 1 2\n").unwrap_err().line, 1);
        assert!(parse_obj("v 0 0 0\nf 1 0 1\n").is_err());
        assert!(parse_obj("v 0 0 0\nf 1 -5 1\n").is_err());
        assert!(parse_obj("f 1 2\n").is_err());
    }
}
