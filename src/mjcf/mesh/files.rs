//! The mesh files MuJoCo 4.0 reads, read as MuJoCo reads them: binary STL
//! (its STL decoder reads no ASCII STL), Wavefront OBJ (its decoder is
//! tinyobjloader: the first shape's faces, quads split along their shorter
//! diagonal, larger polygons cut by its ear clipping, every `v` line a
//! vertex), and MuJoCo's own MSH.
//!
//! Vertices stay single precision, as MuJoCo keeps them until it processes
//! the mesh. The readers are written here rather than taken from a crate:
//! the formats are small, and the rules that change mass properties (which
//! vertices count, how quads split, what is refused) are MuJoCo's own.

use std::collections::HashMap;

/// Vertices and triangles as MuJoCo holds them before processing.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct RawMesh {
    /// Vertex positions.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as indices into `vertices` (not yet checked); empty when
    /// the faces are to come from the convex hull.
    pub faces: Vec<[i64; 3]>,
}

/// The mesh formats, told apart by the file's extension and `content_type`
/// as MuJoCo 4.0 does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MeshFormat {
    /// `.stl`.
    Stl,
    /// `.obj`.
    Obj,
    /// `.msh`.
    Msh,
}

impl MeshFormat {
    /// The format of a file name, by its extension (in any case, as
    /// MuJoCo compares them).
    pub fn of(file: &str) -> Option<Self> {
        let extension = file.rsplit_once('.')?.1.to_ascii_lowercase();
        match extension.as_str() {
            "stl" => Some(Self::Stl),
            "obj" => Some(Self::Obj),
            "msh" => Some(Self::Msh),
            _ => None,
        }
    }

    /// The format MuJoCo 4.0 reads a mesh file in, given its `content_type`
    /// (as observed with each format and type): a well-formed type
    /// ("type/subtype", then optionally ";parameter=value") that is
    /// model/vnd.mujoco.msh reads MSH whatever the extension; any other
    /// well-formed type leaves STL and OBJ to the extension and finds no
    /// reader for an .msh file; a malformed or absent one leaves it all to
    /// the extension.
    pub fn of_mesh(file: &str, content_type: Option<&str>) -> Option<Self> {
        match content_type.and_then(media_type) {
            Some("model/vnd.mujoco.msh") => Some(Self::Msh),
            Some(_) => Self::of(file).filter(|format| *format != Self::Msh),
            None => Self::of(file),
        }
    }
}

/// The "type/subtype" of a well-formed content type, by MuJoCo's rule: a
/// '/' that is not last, and a ';' only after it, followed by an '='.
fn media_type(content_type: &str) -> Option<&str> {
    let slash = content_type.find('/').filter(|&n| n + 1 < content_type.len())?;
    match content_type.find(';') {
        None => Some(content_type),
        Some(semicolon) if semicolon > slash && content_type.find('=').is_some_and(|eq| eq > semicolon) => {
            Some(&content_type[..semicolon])
        }
        Some(_) => None,
    }
}

/// Reads a binary STL file: an 80-byte header, the number of triangles, and
/// 50 bytes per triangle (normal, three vertices, attribute). MuJoCo merges
/// vertices with identical bit patterns.
pub(crate) fn read_stl(bytes: &[u8]) -> Result<RawMesh, String> {
    if bytes.is_empty() {
        return Err("the STL file is empty".into());
    }
    if bytes.len() < 84 {
        return Err("invalid header in STL file".into());
    }
    let count = i32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
    if !(1..=200_000).contains(&count) {
        return Err(format!(
            "the number of faces should be between 1 and 200000, found {count}; perhaps this is an \
             ASCII STL file, which MuJoCo does not read (convert it to binary STL)"
        ));
    }
    let count = count as usize;
    if bytes.len() - 84 != 50 * count {
        return Err(format!(
            "wrong size: {} triangles need {} bytes, the file has {}; perhaps this is an ASCII STL file, \
             which MuJoCo does not read (convert it to binary STL)",
            count,
            84 + 50 * count,
            bytes.len()
        ));
    }
    let mut mesh = RawMesh::default();
    let mut index_of: HashMap<[u32; 3], i64> = HashMap::new();
    for triangle in bytes[84..].chunks_exact(50) {
        let mut face = [0; 3];
        for (corner, slot) in face.iter_mut().enumerate() {
            let at = 12 * (corner + 1);
            let bits: [u32; 3] = std::array::from_fn(|k| {
                let b = &triangle[at + 4 * k..at + 4 * k + 4];
                u32::from_le_bytes([b[0], b[1], b[2], b[3]])
            });
            let vertex = bits.map(f32::from_bits);
            if vertex.iter().any(|x| x.abs() > 2f32.powi(30)) {
                return Err("a vertex exceeds MuJoCo's bound of 2^30".into());
            }
            *slot = *index_of.entry(bits).or_insert_with(|| {
                mesh.vertices.push(vertex);
                mesh.vertices.len() as i64 - 1
            });
        }
        mesh.faces.push(face);
    }
    Ok(mesh)
}

/// Reads a Wavefront OBJ file: every `v` line is a vertex; the faces of the
/// first shape (up to the first `o` or `g` line after a face) are the mesh's,
/// triangles as they are, quads split along their shorter diagonal and
/// larger polygons cut as [`clip_ears`] does (tinyobjloader's rules, which
/// MuJoCo's decoder relies on).
pub(crate) fn read_obj(text: &str) -> Result<RawMesh, String> {
    let mut mesh = RawMesh::default();
    let mut first_shape_done = false;
    for (number, line) in text.lines().enumerate() {
        let line_number = number + 1;
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => {
                let values: Vec<f64> = tokens
                    .take(3)
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("line {line_number}: a vertex needs three numbers"))?;
                let [x, y, z] = values[..] else {
                    return Err(format!("line {line_number}: a vertex needs three numbers"));
                };
                mesh.vertices.push([x as f32, y as f32, z as f32]);
            }
            Some("o" | "g") if !mesh.faces.is_empty() => first_shape_done = true,
            Some("f") if !first_shape_done => {
                let corners = tokens
                    .map(|token| vertex_index(token, mesh.vertices.len()))
                    .collect::<Option<Vec<i64>>>()
                    .ok_or_else(|| format!("line {line_number}: a face corner is not a valid vertex reference"))?;
                match corners[..] {
                    [a, b, c] => mesh.faces.push([a, b, c]),
                    [a, b, c, d] => mesh.faces.extend(split_quad(&mesh.vertices, [a, b, c, d])),
                    // MuJoCo 4.0 keeps no triangle of a polygon of more than
                    // MAX_CUT_CORNERS corners (observed: regular and irregular
                    // polygons of 101 corners and more leave nothing, of 100 are cut).
                    _ if corners.len() > MAX_CUT_CORNERS => {}
                    [_, _, _, _, _, ..] => {
                        // tinyobjloader cuts a polygon with the vertices read when its
                        // shape ends; nudyn cuts it where it stands, which is the same
                        // only if every corner is read by then.
                        let points = corners
                            .iter()
                            .map(|&i| usize::try_from(i).ok().and_then(|i| mesh.vertices.get(i).copied()))
                            .collect::<Option<Vec<[f32; 3]>>>()
                            .ok_or_else(|| {
                                format!(
                                    "line {line_number}: a face of {} vertices refers to a vertex not defined \
                                     before it (nudyn cuts such polygons only with their vertices known)",
                                    corners.len()
                                )
                            })?;
                        mesh.faces.extend(clip_ears(&points).into_iter().map(|triangle| triangle.map(|k| corners[k])));
                    }
                    _ => return Err(format!("line {line_number}: a face needs three vertices at least")),
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

/// The 0-based vertex of a face corner `v`, `v/t`, `v//n` or `v/t/n`
/// (negative: counted back from the last vertex read so far).
fn vertex_index(token: &str, vertices_so_far: usize) -> Option<i64> {
    let index: i64 = token.split('/').next()?.parse().ok()?;
    match index {
        0 => None,
        i if i > 0 => Some(i - 1),
        i => Some(vertices_so_far as i64 + i),
    }
}

/// tinyobjloader's split of a quad into two triangles, along the shorter
/// diagonal in single precision (0–2 when strictly shorter, else 1–3).
fn split_quad(vertices: &[[f32; 3]], quad: [i64; 4]) -> [[i64; 3]; 2] {
    let [a, b, c, d] = quad;
    let position = |i: i64| usize::try_from(i).ok().and_then(|i| vertices.get(i).copied());
    let squared = |p: [f32; 3], q: [f32; 3]| {
        let e = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
    };
    match (position(a), position(b), position(c), position(d)) {
        (Some(pa), Some(pb), Some(pc), Some(pd)) if squared(pa, pc) >= squared(pb, pd) => [[a, b, d], [b, c, d]],
        // Out-of-range corners are reported when the faces are checked.
        _ => [[a, b, c], [a, c, d]],
    }
}

/// The most corners of an OBJ polygon that MuJoCo 4.0 cuts into triangles.
const MAX_CUT_CORNERS: usize = 100;

/// The triangles, as positions in `points`, into which tinyobjloader (as
/// compiled into MuJoCo 4.0, without its optional earcut) cuts a polygon of
/// five corners or more. Its ear clipping, in single precision, is not a
/// proper triangulation, and MuJoCo integrates exactly what it leaves:
///
/// - The plane: the first corner k (from 0) where |e0 × e1| has a component
///   above f32::EPSILON, with e0 = p[k+1] − p[k], e1 = p[k+2] − p[k+1],
///   picks the axes: (y, z) when that component is x and strictly the
///   largest; else (x, y) when z is strictly the largest, else (x, z). With
///   no such corner, (y, z).
/// - From a guess g = 0 in the remaining cycle, the candidate ear is the
///   corners g, g+1, g+2. It is passed over (g += 1) when its turn
///   e0 × e1 times the signed area of the triangle (origin, p[g], p[g+1])
///   is negative: the test compares with the origin, not with the
///   polygon's winding, so convex corners are passed over too; or when a
///   further corner of the cycle lies inside it by the even-odd crossing
///   test. Otherwise it is emitted and corner g+1 leaves the cycle (g
///   stays).
/// - The cycle's size gives the number of guesses allowed without removing
///   a corner (one fewer on the first round); when they run out, the
///   corners left are dropped. The last three form the final triangle.
///
/// tests/python/test_mesh_inertia.py compares the mass properties with
/// MuJoCo's on polygons this cuts in full and in part.
fn clip_ears(points: &[[f32; 3]]) -> Vec<[usize; 3]> {
    let count = points.len();
    let mut axes = [1, 2];
    for k in 0..count {
        let [p0, p1, p2] = [k, k + 1, k + 2].map(|i| points[i % count]);
        let e0 = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
        let e1 = [p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]];
        let cx = (e0[1] * e1[2] - e0[2] * e1[1]).abs();
        let cy = (e0[2] * e1[0] - e0[0] * e1[2]).abs();
        let cz = (e0[0] * e1[1] - e0[1] * e1[0]).abs();
        if cx > f32::EPSILON || cy > f32::EPSILON || cz > f32::EPSILON {
            if !(cx > cy && cx > cz) {
                axes = if cz > cx && cz > cy { [0, 1] } else { [0, 2] };
            }
            break;
        }
    }
    let flat = |i: usize| [points[i][axes[0]], points[i][axes[1]]];
    let mut cycle: Vec<usize> = (0..count).collect();
    let mut triangles = Vec::with_capacity(count - 2);
    let mut guess = 0;
    let mut guesses_left = count;
    let mut size_before = count;
    while cycle.len() > 3 && guesses_left > 0 {
        let size = cycle.len();
        if guess >= size {
            guess -= size;
        }
        if size == size_before {
            guesses_left -= 1;
        } else {
            size_before = size;
            guesses_left = size;
        }
        let ear = [0, 1, 2].map(|k| cycle[(guess + k) % size]);
        let [a, b, c] = ear.map(flat);
        let turn = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        let area_from_origin = (a[0] * b[1] - a[1] * b[0]) * 0.5;
        let crosses_inside = || (3..size).any(|k| crossings_inside([a, b, c], flat(cycle[(guess + k) % size])));
        if turn * area_from_origin < 0.0 || crosses_inside() {
            guess += 1;
            continue;
        }
        triangles.push(ear);
        cycle.remove((guess + 1) % size);
    }
    if let [a, b, c] = cycle[..] {
        triangles.push([a, b, c]);
    }
    triangles
}

/// The even-odd crossing test tinyobjloader uses (W. Randolph Franklin's
/// pnpoly) for a point in a triangle, in single precision: points on an
/// edge fall in or out by rounding.
fn crossings_inside(triangle: [[f32; 2]; 3], point: [f32; 2]) -> bool {
    let mut inside = false;
    for (i, j) in [(0, 2), (1, 0), (2, 1)] {
        let (pi, pj) = (triangle[i], triangle[j]);
        if (pi[1] > point[1]) != (pj[1] > point[1])
            && point[0] < (pj[0] - pi[0]) * (point[1] - pi[1]) / (pj[1] - pi[1]) + pi[0]
        {
            inside = !inside;
        }
    }
    inside
}

/// Reads MuJoCo's MSH format: four little-endian int32 counts (vertices,
/// normals, texture coordinates, faces), then float32 vertices, normals and
/// texture coordinates and int32 faces.
pub(crate) fn read_msh(bytes: &[u8]) -> Result<RawMesh, String> {
    if bytes.is_empty() {
        return Err("the MSH file is empty".into());
    }
    if bytes.len() < 16 {
        return Err("missing header in MSH file".into());
    }
    let int_at = |at: usize| i32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let [nvert, nnormal, ntexcoord, nface] = [0, 4, 8, 12].map(int_at);
    if nvert < 4
        || nface < 0
        || nnormal < 0
        || ntexcoord < 0
        || (nnormal > 0 && nnormal != nvert)
        || (ntexcoord > 0 && ntexcoord != nvert)
    {
        return Err(format!(
            "invalid sizes in MSH file: {nvert} vertices, {nnormal} normals, {ntexcoord} texture coordinates, \
             {nface} faces"
        ));
    }
    let [nvert, nnormal, ntexcoord, nface] = [nvert, nnormal, ntexcoord, nface].map(|n| n as usize);
    let expected = 16 + 4 * (3 * nvert + 3 * nnormal + 2 * ntexcoord + 3 * nface);
    if bytes.len() != expected {
        return Err(format!(
            "unexpected file size in MSH file: {} bytes where the header needs {expected}",
            bytes.len()
        ));
    }
    let float_at = |at: usize| f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let vertices = (0..nvert).map(|v| std::array::from_fn(|k| float_at(16 + 4 * (3 * v + k)))).collect();
    let faces_at = 16 + 4 * (3 * nvert + 3 * nnormal + 2 * ntexcoord);
    let faces = (0..nface).map(|f| std::array::from_fn(|k| i64::from(int_at(faces_at + 4 * (3 * f + k))))).collect();
    Ok(RawMesh { vertices, faces })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_split_along_the_shorter_diagonal() {
        let vertices = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.5, 1.0, 0.5]];
        // 0–2 is longer than 1–3.
        assert_eq!(split_quad(&vertices, [0, 1, 2, 3]), [[0, 1, 3], [1, 2, 3]]);
        let vertices = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(split_quad(&vertices, [0, 1, 2, 3]), [[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn polygons_are_cut_as_tinyobjloader_cuts_them() {
        // A hexagon around the origin: every ear passes, a fan from corner 0.
        let hexagon =
            [[1.0, 0.0, 0.0], [0.5, 0.8, 0.0], [-0.5, 0.8, 0.0], [-1.0, 0.0, 0.0], [-0.5, -0.8, 0.0], [0.5, -0.8, 0.0]];
        assert_eq!(clip_ears(&hexagon), [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]]);
        // A non-convex octagon away from the origin: MuJoCo 4.0 keeps these
        // three triangles (its mesh_face), a part of the polygon.
        let octagon = [
            [1.661503, 0.06516655, 2.5037863],
            [0.6883801, 0.768698, 2.5037863],
            [1.3455006, 0.7726478, 2.5037863],
            [1.3143071, 0.91906196, 2.5037863],
            [1.5398933, 1.2994828, 2.5037863],
            [1.5998256, 1.4555191, 2.5037863],
            [1.9395537, 1.6061885, 2.5037863],
            [2.3156548, 1.4126376, 2.5037863],
        ];
        assert_eq!(clip_ears(&octagon), [[3, 4, 5], [5, 6, 7], [5, 7, 0]]);
        let text = "v 1 0 0\nv 0.5 0.8 0\nv -0.5 0.8 0\nv -1 0 0\nv -0.5 -0.8 0\nv 0.5 -0.8 0\nf 2 3 4 5 6 1\n";
        assert_eq!(read_obj(text).unwrap().faces, [[1, 2, 3], [1, 3, 4], [1, 4, 5], [1, 5, 0]]);
    }

    #[test]
    fn truncated_and_ascii_stl_are_refused() {
        assert!(read_stl(b"").unwrap_err().contains("empty"));
        assert!(read_stl(b"solid x").unwrap_err().contains("header"));
        let mut ascii = b"solid cube\n".to_vec();
        ascii.resize(200, b' ');
        assert!(read_stl(&ascii).unwrap_err().contains("ASCII"));
    }

    #[test]
    fn obj_takes_the_first_shape_and_every_vertex() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\no a\nf 1 3 2\nf -4 -3 -1\ng b\nf 1 2 3\n";
        let mesh = read_obj(text).unwrap();
        assert_eq!(mesh.vertices.len(), 5);
        assert_eq!(mesh.faces, vec![[0, 2, 1], [1, 2, 4]]);
        assert!(read_obj("v 0 0 0\nf 1 2 3 4 5\n").unwrap_err().contains("not defined before it"));
        assert!(read_obj("v 0 0 0\nv 1 0 0\nf 1 2\n").unwrap_err().contains("three vertices"));
        assert!(read_obj("v 0 0\n").unwrap_err().contains("three numbers"));
        assert!(read_obj("f 1/2/3 0 2\n").unwrap_err().contains("vertex reference"));
    }

    #[test]
    fn msh_sizes_are_checked() {
        assert!(read_msh(&[0; 8]).unwrap_err().contains("header"));
        let mut header = Vec::new();
        for n in [4i32, 0, 0, 1] {
            header.extend(n.to_le_bytes());
        }
        assert!(read_msh(&header).unwrap_err().contains("unexpected file size"));
    }
}
