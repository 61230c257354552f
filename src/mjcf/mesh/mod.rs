//! Mesh assets and their mass properties, computed as MuJoCo 4.0's compiler
//! does (`mjCMesh::Process`): the file read as MuJoCo reads it
//! ([`files`]), `refpos`, `refquat` and `scale` applied, then the volume (or
//! the surface area with `inertia="shell"`), the centre of mass and the
//! inertia of the unit-density solid, whose centre and principal axes
//! (MuJoCo's `mjuu_eig3`) become the mesh frame that a mesh geom's frame
//! absorbs.
//!
//! The four `inertia` modes differ in which triangles count and how:
//! `legacy` (MuJoCo's default) adds every triangle's tetrahedron to the
//! centroid of the surface with a positive volume, so a non-convex or open
//! mesh weighs more than its solid; `exact` adds them signed (the
//! divergence theorem, exact for a closed, consistently oriented mesh,
//! which MuJoCo checks); `convex` integrates the convex hull ([`hull`]);
//! `shell` spreads the mass over the surface.

mod files;
mod hull;

use std::cell::OnceCell;
use std::collections::HashMap;
use std::path::PathBuf;

use files::{MeshFormat, RawMesh};

use super::attributes::{Attribute, Read, read_into, set};
use super::defaults::GeomKind;
use super::element::Element;
use super::error::MjcfError;
use super::inertia::{self, Eigen, principal_axes, quat_array, quat_to_mat};
use crate::math::Mat3;

/// MuJoCo's `mjMINVAL`.
const MIN_VALUE: f64 = 1e-15;

/// `<mesh>` in `<asset>` (MuJoCo 4.0 schema): its attributes and how each
/// is read. Those read into [`MeshSettings`] are those a `<default>` class
/// may set ([`mesh_default_attributes`]); the reader reads the others when
/// it declares the mesh ([`declare`]).
pub(crate) const MESH_ATTRIBUTES: &[Attribute<MeshSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::by_reader("content_type"),
    Attribute::by_reader("file"),
    Attribute::by_reader("vertex"),
    Attribute::no_effect("normal"),
    Attribute::no_effect("texcoord"),
    Attribute::by_reader("face"),
    Attribute::by_reader("refpos"),
    Attribute::by_reader("refquat"),
    Attribute::into("scale", |s, e, a| set(&mut s.scale, e.numbers(a)?)),
    Attribute::no_effect("smoothnormal"),
    Attribute::into("maxhullvert", read_max_hull_vertices),
    Attribute::into("inertia", |s, e, a| set(&mut s.inertia, e.keyword(a, &MESH_INERTIA)?)),
    // Refused by the reader: nudyn reads meshes from files or vertex lists.
    Attribute::by_reader("builtin"),
    Attribute::no_effect("params"),
    Attribute::no_effect("material"),
];

/// The attributes of `<mesh>` in `<default>`: those read into its settings.
pub(crate) fn mesh_default_attributes() -> Vec<&'static str> {
    MESH_ATTRIBUTES.iter().filter(|a| matches!(a.read, Read::Into(_))).map(|a| a.name).collect()
}

/// The keywords of `<mesh inertia>`.
const MESH_INERTIA: [(&str, MeshInertia); 4] = [
    ("legacy", MeshInertia::Legacy),
    ("convex", MeshInertia::Convex),
    ("exact", MeshInertia::Exact),
    ("shell", MeshInertia::Shell),
];

/// `maxhullvert`: -1 (no limit) or more than 3.
fn read_max_hull_vertices(settings: &mut MeshSettings, element: &Element, attribute: &str) -> Result<(), MjcfError> {
    if let Some([limit]) = element.integers(attribute)? {
        if limit != -1 && limit < 4 {
            return Err(element.invalid("maxhullvert must be larger than 3"));
        }
        settings.max_hull_vertices = limit;
    }
    Ok(())
}

/// How a mesh's mass is distributed (`<mesh inertia>`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MeshInertia {
    /// `legacy`, MuJoCo's default: every triangle's volume counted positive.
    Legacy,
    /// `convex`: the convex hull's volume.
    Convex,
    /// `exact`: the signed volume of a closed mesh.
    Exact,
    /// `shell`: the mass on the surface.
    Shell,
}

/// The `<mesh>` attributes that a default class sets.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MeshSettings {
    /// `scale`.
    pub scale: [f64; 3],
    /// `inertia`.
    pub inertia: MeshInertia,
    /// `maxhullvert` (-1: no limit).
    pub max_hull_vertices: i32,
}

impl Default for MeshSettings {
    /// MuJoCo's built-in mesh defaults.
    fn default() -> Self {
        Self { scale: [1.0; 3], inertia: MeshInertia::Legacy, max_hull_vertices: -1 }
    }
}

impl MeshSettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(MESH_ATTRIBUTES, self, element)
    }
}

/// A processed mesh asset: what its geoms need.
#[derive(Clone, Debug)]
pub(crate) struct Mesh {
    /// Line of the `<mesh>` element.
    pub line: u32,
    /// The mesh frame in the mesh's file coordinates (after `refpos`,
    /// `refquat` and `scale`): the centre of mass (MuJoCo's `mesh_pos`)…
    pub pos: [f64; 3],
    /// …and the principal axes (`mesh_quat`, w x y z).
    pub quat: [f64; 4],
    /// Volume, or surface area for `inertia="shell"`.
    pub volume: f64,
    /// Half sizes of the box with the mesh's unit-density inertia (MuJoCo's
    /// inertia box), from which a geom's moments follow.
    pub box_half: [f64; 3],
    /// The corners (lowest, highest) of the box aligned with the mesh frame
    /// that holds every vertex, in that frame (MuJoCo's `aamm`).
    pub aabb: [[f64; 3]; 2],
    /// Why MuJoCo could not build the convex hull it needs for collisions
    /// (flat, collinear or repeated vertices), if it could not.
    pub hull_error: Option<String>,
}

impl Mesh {
    /// A geom's principal moments for its mass (MuJoCo's `SetInertia` for
    /// meshes).
    pub fn principal_moments(&self, mass: f64) -> [f64; 3] {
        let [a, b, c] = self.box_half;
        [mass * (b * b + c * c) / 3.0, mass * (a * a + c * c) / 3.0, mass * (a * a + b * b) / 3.0]
    }

    /// A point given in the mesh frame, in the mesh's file coordinates.
    pub fn frame_point(&self, point: &[f64; 3]) -> [f64; 3] {
        let m = quat_to_mat(&self.quat);
        std::array::from_fn(|r| m[3 * r] * point[0] + m[3 * r + 1] * point[1] + m[3 * r + 2] * point[2] + self.pos[r])
    }

    /// The size of a primitive geom fitted to this mesh, and its centre in
    /// the mesh frame (MuJoCo's `mjCMesh::FitGeom`). From the inertia box:
    /// a sphere's radius is the mean of the three half sizes; a cylinder's
    /// radius the mean of the first two and its half length the third; a
    /// capsule's the same radius and the third less half the radius (not
    /// below 0); an ellipsoid's or box's the half sizes; centred on the
    /// mesh frame. With `<compiler fitaabb>`, from the box `aabb` instead,
    /// centred on it: the smallest primitive whose own box holds it (a
    /// capsule's half length less its radius). The sizes a type does not use
    /// keep the geom's own; all three are then scaled by `fitscale`. `None`
    /// for a geom type that cannot be fitted.
    pub fn fit(
        &self,
        kind: GeomKind,
        mut size: [f64; 3],
        fit_aabb: bool,
        fit_scale: f64,
    ) -> Option<([f64; 3], [f64; 3])> {
        let ([a, b, c], center) = if fit_aabb {
            let [low, high] = self.aabb;
            let center: [f64; 3] = std::array::from_fn(|k| (low[k] + high[k]) / 2.0);
            (std::array::from_fn(|k| high[k] - center[k]), center)
        } else {
            (self.box_half, [0.0; 3])
        };
        match (kind, fit_aabb) {
            (GeomKind::Sphere, true) => size[0] = a.max(b).max(c),
            (GeomKind::Sphere, false) => size[0] = (a + b + c) / 3.0,
            (GeomKind::Cylinder, true) => size[..2].copy_from_slice(&[a.max(b), c]),
            (GeomKind::Cylinder, false) => size[..2].copy_from_slice(&[(a + b) / 2.0, c]),
            (GeomKind::Capsule, true) => size[..2].copy_from_slice(&[a.max(b), c - a.max(b)]),
            (GeomKind::Capsule, false) => size[..2].copy_from_slice(&[(a + b) / 2.0, (c - (a + b) / 4.0).max(0.0)]),
            (GeomKind::Ellipsoid | GeomKind::Box, _) => size = [a, b, c],
            (GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf, _) => return None,
        }
        Some((size.map(|x| x * fit_scale), center))
    }
}

/// A `<mesh>` asset as declared: its attributes checked, its file not yet
/// read. The file is read and the mesh processed the first time a geom
/// needs it ([`MeshAsset::mesh`]): a mesh nothing needs (one only world
/// geoms use, say) is never opened, so a missing or huge file there does
/// not stop the import.
#[derive(Debug)]
pub(crate) struct MeshAsset {
    /// Line of the `<mesh>` element.
    pub line: u32,
    /// The element as messages show it.
    label: String,
    settings: MeshSettings,
    refpos: [f64; 3],
    refquat: [f64; 4],
    /// Where the file is read, and its format.
    file: Option<(PathBuf, MeshFormat)>,
    /// `vertex`, `face`.
    vertices: Option<Vec<[f32; 3]>>,
    faces: Option<Vec<[i64; 3]>>,
    /// The mesh once processed.
    processed: OnceCell<Mesh>,
}

/// Checks a `<mesh>` asset's attributes with its class's settings.
pub(crate) fn declare(
    element: &Element,
    defaults: &MeshSettings,
    file_path: Option<PathBuf>,
) -> Result<MeshAsset, MjcfError> {
    if element.has("builtin") {
        return Err(element.unsupported("built-in meshes (write the mesh out to a file)"));
    }
    if let Some(child) = element.children().next() {
        return Err(child.unsupported("mesh plugins"));
    }
    let mut settings = defaults.clone();
    settings.apply(element)?;
    let refpos = element.numbers::<3>("refpos")?.unwrap_or_default();
    let refquat = element.numbers::<4>("refquat")?.unwrap_or([1.0, 0.0, 0.0, 0.0]);
    let file = match (element.text("file"), file_path) {
        (Some(file), Some(path)) => {
            let content_type = element.text("content_type");
            let format = MeshFormat::of_mesh(file, content_type).ok_or_else(|| match content_type {
                Some(content_type) if MeshFormat::of(file).is_some() => element
                    .invalid(format!("no decoder found for mesh file '{file}' with content_type '{content_type}'")),
                _ => element.unsupported(format!("mesh file '{file}': nudyn reads .stl, .obj and .msh files")),
            })?;
            Some((path, format))
        }
        _ => None,
    };
    let vertices = match element.text("vertex") {
        Some(text) => {
            let values: Vec<f32> = parse_list(text).ok_or_else(|| element.bad_value("vertex", "numbers"))?;
            if !values.len().is_multiple_of(3) {
                return Err(element.invalid("vertex data must be a multiple of 3"));
            }
            Some(values.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect())
        }
        None => None,
    };
    let faces = match element.text("face") {
        Some(text) => {
            let values: Vec<i64> = parse_list(text).ok_or_else(|| element.bad_value("face", "integers"))?;
            if !values.len().is_multiple_of(3) {
                return Err(element.invalid("face data must be a multiple of 3"));
            }
            Some(values.chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect())
        }
        None => None,
    };
    Ok(MeshAsset {
        line: element.line,
        label: element.label(),
        settings,
        refpos,
        refquat,
        file,
        vertices,
        faces,
        processed: OnceCell::new(),
    })
}

impl MeshAsset {
    /// The processed mesh, its file read the first time.
    pub fn mesh(&self) -> Result<&Mesh, MjcfError> {
        if let Some(mesh) = self.processed.get() {
            return Ok(mesh);
        }
        let mesh = self.process()?;
        Ok(self.processed.get_or_init(|| mesh))
    }

    fn invalid(&self, reason: String) -> MjcfError {
        MjcfError::Invalid { line: self.line, element: self.label.clone(), reason }
    }

    /// Reads the file, if any, and processes the mesh.
    fn process(&self) -> Result<Mesh, MjcfError> {
        let mut raw = RawMesh::default();
        if let Some((path, format)) = &self.file {
            let bytes = crate::mjcf::read_regular_file(path)
                .map_err(|e| self.invalid(format!("cannot read mesh file '{}': {e}", path.display())))?;
            let in_file = |reason: String| self.invalid(format!("mesh file '{}': {reason}", path.display()));
            raw = match format {
                MeshFormat::Stl => files::read_stl(&bytes),
                MeshFormat::Obj => std::str::from_utf8(&bytes)
                    .map_err(|_| "the OBJ file is not UTF-8 text".to_string())
                    .and_then(files::read_obj),
                MeshFormat::Msh => files::read_msh(&bytes),
            }
            .map_err(in_file)?;
        }
        if let Some(vertices) = &self.vertices {
            if !raw.vertices.is_empty() {
                return Err(self.invalid("repeated vertex specification (both 'file' and 'vertex')".into()));
            }
            raw.vertices.clone_from(vertices);
        }
        if let Some(faces) = &self.faces {
            if !raw.faces.is_empty() {
                return Err(self.invalid("repeated face specification (both 'file' and 'face')".into()));
            }
            raw.faces.clone_from(faces);
        }
        let source = match &self.file {
            Some((path, _)) => format!("mesh file '{}'", path.display()),
            None => "mesh".to_string(),
        };
        process(raw, &self.settings, self.refpos, self.refquat)
            .map(|mesh| Mesh { line: self.line, ..mesh })
            .map_err(|reason| self.invalid(format!("{source}: {reason}")))
    }
}

/// Parses whitespace-separated values.
fn parse_list<T: std::str::FromStr>(text: &str) -> Option<Vec<T>> {
    text.split_ascii_whitespace().map(|s| s.parse().ok()).collect()
}

/// MuJoCo's `triangle`: area, unit normal (left as the raw cross product for
/// a face below mjMINVAL, whose area is then 0) and centre.
fn triangle(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> (f64, [f64; 3], [f64; 3]) {
    let center = std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let mut normal = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let length = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    if length < MIN_VALUE {
        return (0.0, normal, center);
    }
    normal = normal.map(|n| n / length);
    (0.5 * length, normal, center)
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// MuJoCo's checks before it asks qhull for a hull: a second distinct
/// vertex, a third off their line, a fourth off their plane.
fn hull_precondition(vertices: &[[f64; 3]]) -> Result<(), String> {
    let distance = |a: &[f64; 3], b: &[f64; 3]| {
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        dot(&d, &d).sqrt()
    };
    let first = &vertices[0];
    let Some((second, length1)) =
        vertices.iter().enumerate().skip(1).map(|(i, v)| (i, distance(v, first))).find(|&(_, l)| l > MIN_VALUE)
    else {
        return Err("its vertices are all in one place: no convex hull (consider a small sphere)".into());
    };
    let edge1: [f64; 3] = std::array::from_fn(|k| vertices[second][k] - first[k]);
    let mut plane = None;
    for (i, v) in vertices.iter().enumerate().skip(1) {
        if i == second {
            continue;
        }
        let edge2: [f64; 3] = std::array::from_fn(|k| v[k] - first[k]);
        let length2 = dot(&edge2, &edge2).sqrt();
        if length2 < MIN_VALUE {
            continue;
        }
        let normal = [
            edge1[1] * edge2[2] - edge1[2] * edge2[1],
            edge1[2] * edge2[0] - edge1[0] * edge2[2],
            edge1[0] * edge2[1] - edge1[1] * edge2[0],
        ];
        let norm = dot(&normal, &normal).sqrt();
        if norm > MIN_VALUE * length1 * length2 {
            plane = Some(normal.map(|n| n / norm));
            break;
        }
    }
    let Some(normal) = plane else {
        return Err("its vertices are collinear: no convex hull (consider a thin capsule)".into());
    };
    let offset = dot(&normal, first);
    if vertices.iter().all(|v| (dot(&normal, v) - offset).abs() <= MIN_VALUE * length1) {
        return Err("its vertices are coplanar: no convex hull (consider a thin box)".into());
    }
    Ok(())
}

/// `mjCMesh::Process` up to the mesh frame, for the mass properties.
fn process(raw: RawMesh, settings: &MeshSettings, refpos: [f64; 3], refquat: [f64; 4]) -> Result<Mesh, String> {
    if raw.vertices.len() < 4 {
        return Err(format!("at least 4 vertices required, found {}", raw.vertices.len()));
    }
    if let Some(i) = raw.vertices.iter().position(|v| v.iter().any(|x| !x.is_finite())) {
        return Err(format!("vertex {i} is not finite"));
    }
    let count = raw.vertices.len() as i64;
    let mut faces = Vec::with_capacity(raw.faces.len());
    for (f, face) in raw.faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v < 0 || v >= count) {
            return Err(format!("in face {f}, vertex index {v} does not exist"));
        }
        faces.push(face.map(|v| v as usize));
    }
    let mut vertices: Vec<[f64; 3]> = raw.vertices.iter().map(|v| v.map(f64::from)).collect();

    // Two faces running along the same edge in the same direction.
    let mut half_edges = Vec::new();
    for &[a, b, c] in &faces {
        if triangle(&vertices[a], &vertices[b], &vertices[c]).0 > MIN_VALUE.sqrt() {
            half_edges.extend([(a, b), (b, c), (c, a)]);
        }
    }
    half_edges.sort_unstable();
    if settings.inertia == MeshInertia::Exact
        && let Some(pair) = half_edges.windows(2).find(|pair| pair[0] == pair[1])
    {
        let (a, b) = pair[0];
        return Err(format!(
            "faces have inconsistent orientation (an edge from vertex {} to vertex {} is in two faces, \
             counted from 1); inertia=\"exact\" needs a closed, consistently oriented mesh",
            a + 1,
            b + 1
        ));
    }

    let hull_error = hull_precondition(&vertices).err();
    let needs_hull = settings.inertia == MeshInertia::Convex || faces.is_empty();
    let mut hull_faces =
        if needs_hull { convex_hull_faces(&vertices, hull_error.as_ref(), settings)? } else { Vec::new() };
    if faces.is_empty() {
        faces = hull_faces.clone();
    }
    // A mirroring scale turns the faces inside out: reverse them.
    if settings.scale[0] * settings.scale[1] * settings.scale[2] <= 0.0 {
        for face in faces.iter_mut().chain(&mut hull_faces) {
            face.swap(1, 2);
        }
    }

    apply_transformations(&mut vertices, settings.scale, refpos, refquat);

    // Centroid of the surface, the apex of every triangle's tetrahedron.
    let mut face_center = [0.0; 3];
    let mut total_area = 0.0;
    for &[a, b, c] in &faces {
        let (area, _, center) = triangle(&vertices[a], &vertices[b], &vertices[c]);
        for k in 0..3 {
            face_center[k] += area * center[k];
        }
        total_area += area;
    }
    if total_area < MIN_VALUE {
        return Err(format!("mesh surface area is too small ({total_area})"));
    }
    face_center = face_center.map(|x| x / total_area);

    let mode = settings.inertia;
    let integrated = if mode == MeshInertia::Convex { &hull_faces } else { &faces };
    let com = if mode == MeshInertia::Shell {
        surface_centroid(&vertices, &faces, &face_center)
    } else {
        let (volume, com) = volume_centroid(&vertices, integrated, &face_center, mode);
        if volume < MIN_VALUE {
            return Err(if volume < 0.0 {
                format!("mesh volume is negative ({volume}): its triangles are misoriented")
            } else {
                format!("mesh volume is too small ({volume}); try inertia=\"shell\"")
            });
        }
        com
    };
    let (volume, tensor) = unit_inertia(&vertices, integrated, &com, mode);
    if !volume.is_finite() || tensor.iter().any(|x| !x.is_finite()) {
        return Err("its volume or inertia overflows: the mesh is too large".into());
    }

    let (quat, box_half, aabb) = mesh_frame(&vertices, &tensor, &com, volume)?;
    Ok(Mesh { line: 0, pos: com, quat, volume, box_half, aabb, hull_error })
}

/// The faces of the convex hull of `vertices` (whose `hull_error` is why
/// they have none, if so), refused past `maxhullvert`.
fn convex_hull_faces(
    vertices: &[[f64; 3]],
    hull_error: Option<&String>,
    settings: &MeshSettings,
) -> Result<Vec<[usize; 3]>, String> {
    if let Some(error) = hull_error {
        return Err(error.clone());
    }
    let hull = hull::convex_hull(vertices).ok_or("its vertices are coplanar: no convex hull")?;
    let mut hull_vertices: Vec<usize> = hull.iter().flatten().copied().collect();
    hull_vertices.sort_unstable();
    hull_vertices.dedup();
    let limit = settings.max_hull_vertices;
    if limit > -1 && hull_vertices.len() > limit as usize {
        return Err(format!(
            "its convex hull has {} vertices, more than maxhullvert=\"{limit}\": MuJoCo would simplify \
             the hull with qhull, which nudyn does not reproduce; raise maxhullvert or remove it",
            hull_vertices.len()
        ));
    }
    Ok(hull)
}

/// A box as its lowest and highest corner.
type BoundingBox = [[f64; 3]; 2];

/// The mesh frame of a mesh with centre of mass `com`, unit-density
/// inertia `tensor` and `volume`: its orientation (the principal axes),
/// the half sizes of its inertia box and the bounding box of `vertices`
/// in it.
fn mesh_frame(
    vertices: &[[f64; 3]],
    tensor: &nalgebra::Matrix3<f64>,
    com: &[f64; 3],
    volume: f64,
) -> Result<([f64; 4], [f64; 3], BoundingBox), String> {
    let (eigenvalues, quat) = principal_axes(tensor, Eigen::Mesh);
    let (quat, [e0, e1, e2]) = (quat_array(&quat), eigenvalues.into());
    if e2 <= 0.0 {
        return Err("an eigenvalue of the mesh inertia is not positive".into());
    }
    let (atol, rtol) = (1e-9, 1e-6);
    if e0 + e1 < e2 * (1.0 - rtol) - atol || e0 + e2 < e1 * (1.0 - rtol) - atol || e1 + e2 < e0 * (1.0 - rtol) - atol {
        return Err(format!("the eigenvalues of the mesh inertia {e0} {e1} {e2} violate A + B >= C"));
    }
    let box_half = [
        0.5 * (6.0 * (e1 + e2 - e0) / volume).sqrt(),
        0.5 * (6.0 * (e0 + e2 - e1) / volume).sqrt(),
        0.5 * (6.0 * (e0 + e1 - e2) / volume).sqrt(),
    ];
    // Every vertex in the mesh frame: moved to the centre, rotated back.
    let rotation = quat_to_mat(&quat);
    let mut aabb: [[f64; 3]; 2] = [[1e10; 3], [-1e10; 3]];
    for v in vertices {
        let d = [v[0] - com[0], v[1] - com[1], v[2] - com[2]];
        for k in 0..3 {
            let local = rotation[k] * d[0] + rotation[3 + k] * d[1] + rotation[6 + k] * d[2];
            aabb[0][k] = aabb[0][k].min(local);
            aabb[1][k] = aabb[1][k].max(local);
        }
    }
    Ok((quat, box_half, aabb))
}

/// `refpos` subtracted, `refquat`'s inverse rotation, then `scale`.
fn apply_transformations(vertices: &mut [[f64; 3]], scale: [f64; 3], refpos: [f64; 3], refquat: [f64; 4]) {
    if refpos != [0.0; 3] {
        for v in vertices.iter_mut() {
            for k in 0..3 {
                v[k] -= refpos[k];
            }
        }
    }
    if refquat != [1.0, 0.0, 0.0, 0.0] {
        let m = quat_to_mat(&inertia::normalize4(refquat));
        for v in vertices.iter_mut() {
            *v = [
                m[0] * v[0] + m[3] * v[1] + m[6] * v[2],
                m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
                m[2] * v[0] + m[5] * v[1] + m[8] * v[2],
            ];
        }
    }
    if scale != [1.0; 3] {
        for v in vertices.iter_mut() {
            for k in 0..3 {
                v[k] *= scale[k];
            }
        }
    }
}

/// Volume and centre of mass from the tetrahedra of the triangles and
/// `apex` (volumes taken positive in legacy mode; MuJoCo's
/// `ComputeVolume`).
fn volume_centroid(vertices: &[[f64; 3]], faces: &[[usize; 3]], apex: &[f64; 3], mode: MeshInertia) -> (f64, [f64; 3]) {
    let mut total = 0.0;
    let mut com = [0.0; 3];
    for &[a, b, c] in faces {
        let (area, normal, center) = triangle(&vertices[a], &vertices[b], &vertices[c]);
        let offset = [center[0] - apex[0], center[1] - apex[1], center[2] - apex[2]];
        let mut volume = dot(&offset, &normal) * area / 3.0;
        if mode == MeshInertia::Legacy {
            volume = volume.abs();
        }
        total += volume;
        for k in 0..3 {
            com[k] += volume * (center[k] * 3.0 / 4.0 + apex[k] / 4.0);
        }
    }
    if total >= MIN_VALUE {
        com = com.map(|x| x / total);
    }
    (total, com)
}

/// Surface area's centre (MuJoCo's `ComputeSurfaceArea`, which weights each
/// triangle's centre as a tetrahedron's with `apex`).
fn surface_centroid(vertices: &[[f64; 3]], faces: &[[usize; 3]], apex: &[f64; 3]) -> [f64; 3] {
    let mut total = 0.0;
    let mut com = [0.0; 3];
    for &[a, b, c] in faces {
        let (area, _, center) = triangle(&vertices[a], &vertices[b], &vertices[c]);
        total += area;
        for k in 0..3 {
            com[k] += area * (center[k] * 3.0 / 4.0 + apex[k] / 4.0);
        }
    }
    if total >= MIN_VALUE { com.map(|x| x / total) } else { com }
}

/// The unit-density inertia about `com` and the volume (or area) again,
/// from each triangle's tetrahedron to `com` (or the triangle itself for a
/// shell): MuJoCo's `ComputeInertia`.
fn unit_inertia(vertices: &[[f64; 3]], faces: &[[usize; 3]], com: &[f64; 3], mode: MeshInertia) -> (f64, Mat3) {
    let centered: Vec<[f64; 3]> = vertices.iter().map(|v| [v[0] - com[0], v[1] - com[1], v[2] - com[2]]).collect();
    const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
    let divisor = if mode == MeshInertia::Shell { 12.0 } else { 20.0 };
    let mut products = [0.0; 6];
    let mut total = 0.0;
    for &[a, b, c] in faces {
        let (d, e, f) = (&centered[a], &centered[b], &centered[c]);
        let (area, normal, center) = triangle(d, e, f);
        let mut volume = if mode == MeshInertia::Shell { area } else { dot(&center, &normal) * area / 3.0 };
        if mode == MeshInertia::Legacy {
            volume = volume.abs();
        }
        total += volume;
        for (j, &(p, q)) in PAIRS.iter().enumerate() {
            products[j] += volume / divisor
                * (2.0 * (d[p] * d[q] + e[p] * e[q] + f[p] * f[q])
                    + d[p] * e[q]
                    + d[q] * e[p]
                    + d[p] * f[q]
                    + d[q] * f[p]
                    + e[p] * f[q]
                    + e[q] * f[p]);
        }
    }
    let [xx, yy, zz, xy, xz, yz] = products;
    let tensor = Mat3::new(yy + zz, -xy, -xz, -xy, xx + zz, -yz, -xz, -yz, xx + yy);
    (total, tensor)
}

/// Mesh assets by name.
pub(crate) type Meshes = HashMap<String, MeshAsset>;

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn cube() -> RawMesh {
        let vertices = (0..8).map(|k| [(k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32]).collect();
        // Outward quads, split into triangles.
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let faces = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
        RawMesh { vertices, faces }
    }

    fn settings(inertia: MeshInertia) -> MeshSettings {
        MeshSettings { inertia, ..MeshSettings::default() }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-14 * b.abs().max(1.0)
    }

    #[test]
    fn unit_cube_in_every_solid_mode() {
        for mode in [MeshInertia::Legacy, MeshInertia::Exact, MeshInertia::Convex] {
            let mesh = process(cube(), &settings(mode), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap();
            assert!(close(mesh.volume, 1.0), "{mode:?}: {}", mesh.volume);
            assert!(mesh.pos.iter().all(|&x| close(x, 0.5)), "{mode:?}: {:?}", mesh.pos);
            // A unit cube of mass 1: 1/6 about every axis through its centre.
            assert!(mesh.principal_moments(1.0).iter().all(|&i| close(i, 1.0 / 6.0)));
        }
    }

    #[test]
    fn unit_cube_shell() {
        let mesh = process(cube(), &settings(MeshInertia::Shell), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap();
        assert!(close(mesh.volume, 6.0));
        // Six unit plates of mass 1/6: the two across the axis 1/36 each, the
        // four along it 1/72 + 1/24 each; 5/18 in all.
        assert!(mesh.principal_moments(1.0).iter().all(|&i| close(i, 5.0 / 18.0)), "{:?}", mesh.principal_moments(1.0));
    }

    #[test]
    fn tetrahedron_against_its_closed_form() {
        // The corner tetrahedron of edge a = 2 (the origin and a along each
        // axis): volume a³/6, centroid a/4 on each axis, and over the solid
        // ∫x² = a⁵/60 and ∫xy = a⁵/120 about the origin.
        let raw = RawMesh {
            vertices: vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]],
            faces: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        };
        let mesh = process(raw, &settings(MeshInertia::Exact), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let a: f64 = 2.0;
        let volume = a.powi(3) / 6.0;
        assert!(close(mesh.volume, volume));
        assert!(mesh.pos.iter().all(|&x| close(x, a / 4.0)));
        // Second moments about the centroid: ∫x² − V c², ∫xy − V c².
        let (c, xx, xy) = (a / 4.0, a.powi(5) / 60.0, a.powi(5) / 120.0);
        let (sxx, sxy) = (xx - volume * c * c, xy - volume * c * c);
        let tensor = Mat3::new(2.0 * sxx, -sxy, -sxy, -sxy, 2.0 * sxx, -sxy, -sxy, -sxy, 2.0 * sxx);
        let expected = nalgebra::SymmetricEigen::new(tensor).eigenvalues;
        let mut expected: Vec<f64> = expected.iter().copied().collect();
        expected.sort_by(|x, y| y.total_cmp(x));
        let moments = mesh.principal_moments(volume);
        for (got, want) in moments.iter().zip(&expected) {
            assert!((got - want).abs() < 1e-13, "{moments:?} vs {expected:?}");
        }
    }

    /// The committed fixtures (tests/fixtures/meshes), read by format.
    fn fixture(name: &str) -> RawMesh {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/meshes").join(name);
        let bytes = std::fs::read(&path).unwrap();
        match MeshFormat::of(name).unwrap() {
            MeshFormat::Stl => files::read_stl(&bytes),
            MeshFormat::Obj => files::read_obj(std::str::from_utf8(&bytes).unwrap()),
            MeshFormat::Msh => files::read_msh(&bytes),
        }
        .unwrap()
    }

    #[test]
    fn every_format_reads_the_same_geometry() {
        for shape in ["cube", "tetrahedron", "l_shape", "open_box"] {
            let meshes = ["stl", "obj", "msh"].map(|format| fixture(&format!("{shape}.{format}")));
            // The same triangles, whatever the order of the vertices.
            let triangles = |mesh: &RawMesh| {
                let mut corners: Vec<[[u32; 3]; 3]> =
                    mesh.faces.iter().map(|f| f.map(|v| mesh.vertices[v as usize].map(f32::to_bits))).collect();
                corners.sort_unstable();
                corners
            };
            assert_eq!(triangles(&meshes[0]), triangles(&meshes[1]), "{shape}: STL and OBJ");
            assert_eq!(triangles(&meshes[0]), triangles(&meshes[2]), "{shape}: STL and MSH");
            for mode in [MeshInertia::Legacy, MeshInertia::Exact, MeshInertia::Convex, MeshInertia::Shell] {
                let [a, b, c] =
                    meshes.clone().map(|m| process(m, &settings(mode), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap());
                for other in [&b, &c] {
                    assert!(close(a.volume, other.volume), "{shape} {mode:?}");
                    assert!(a.pos.iter().zip(&other.pos).all(|(x, y)| (x - y).abs() < 1e-14), "{shape} {mode:?}");
                    assert!(a.box_half.iter().zip(&other.box_half).all(|(x, y)| close(*x, *y)), "{shape} {mode:?}");
                }
            }
        }
    }

    #[test]
    fn the_l_shape_tells_the_modes_apart() {
        // Legacy counts the tetrahedra the surface centroid sees from behind
        // positive; the hull fills the notch. Exact: 12 squares of 0.125² by 0.375.
        let volume =
            |mode| process(fixture("l_shape.stl"), &settings(mode), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap().volume;
        let exact = 7.0 * 0.125 * 0.125 * 0.375;
        assert!(close(volume(MeshInertia::Exact), exact));
        // The hull: the square 0.5 × 0.5 less the triangle beyond the notch's diagonal.
        let hull_area = 0.25 - 0.5 * 0.375 * 0.375;
        assert!(close(volume(MeshInertia::Convex), hull_area * 0.375));
        assert!(volume(MeshInertia::Legacy) > exact * (1.0 + 1e-6));
    }

    #[test]
    fn arbitrary_bytes_give_errors_not_panics() {
        // A fixed linear congruential sequence: damaged fixtures and noise.
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as u32
        };
        let sources = ["cube.stl", "l_shape.msh", "open_box.obj"].map(|name| {
            std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/meshes").join(name)).unwrap()
        });
        for round in 0..3000 {
            let mut bytes = sources[round % 3].clone();
            for _ in 0..1 + next() % 8 {
                let at = next() as usize % bytes.len();
                bytes[at] = match round % 3 {
                    // Text damage stays within what an OBJ file is made of.
                    2 => b"0123456789 -./vfog\n"[next() as usize % 19],
                    _ => next() as u8,
                };
            }
            if round % 7 == 0 {
                bytes.truncate(next() as usize % bytes.len());
            }
            let read = match round % 3 {
                0 => files::read_stl(&bytes),
                1 => files::read_msh(&bytes),
                _ => files::read_obj(&String::from_utf8_lossy(&bytes)),
            };
            if let Ok(raw) = read {
                for mode in [MeshInertia::Legacy, MeshInertia::Convex, MeshInertia::Exact, MeshInertia::Shell] {
                    let _ = process(raw.clone(), &settings(mode), [0.0; 3], [1.0, 0.0, 0.0, 0.0]);
                }
            }
        }
    }

    #[test]
    fn misoriented_and_degenerate_meshes_are_refused() {
        let mut flipped = cube();
        flipped.faces[0].swap(1, 2);
        let error = process(flipped, &settings(MeshInertia::Exact), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(error.contains("inconsistent orientation"), "{error}");
        let mut inside_out = cube();
        for face in &mut inside_out.faces {
            face.swap(1, 2);
        }
        let error = process(inside_out, &settings(MeshInertia::Exact), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(error.contains("negative"), "{error}");
        let flat = RawMesh {
            vertices: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
            faces: vec![],
        };
        let error = process(flat, &settings(MeshInertia::Legacy), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(error.contains("coplanar"), "{error}");
        let huge = MeshSettings { scale: [1e120; 3], ..MeshSettings::default() };
        let error = process(cube(), &huge, [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(error.contains("overflows"), "{error}");
        let out_of_range = RawMesh { faces: vec![[0, 1, 8]], ..cube() };
        let error = process(out_of_range, &settings(MeshInertia::Legacy), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(error.contains("vertex index 8"), "{error}");
    }

    #[test]
    fn primitives_fitted_to_the_l_shape_take_mujocos_sizes_and_frames() {
        // MuJoCo 4.0's geom_size and geom_pos for each kind with fitscale="1.25"
        // and no size of its own, fitted to l_shape.stl (legacy) in a geom at
        // the body's origin, whose geom_quat is the mesh frame's
        // (0.6532814824381892, 0.6532814824381892, 0.2705980500730989, 0.2705980500730989).
        let mesh =
            process(fixture("l_shape.stl"), &settings(MeshInertia::Legacy), [0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let quat = [0.6532814824381892, 0.6532814824381892, 0.2705980500730989, 0.2705980500730989];
        assert!((0..4).all(|k| (mesh.quat[k] - quat[k]).abs() < 1e-12), "{:?}", mesh.quat);
        let inertia_box = (
            [0.177138295958748, 0.17713829595874808, 0.1875],
            [
                (GeomKind::Sphere, [0.2660792379140948, 0.0, 0.0]),
                (GeomKind::Capsule, [0.2147914344804019, 0.2612591275412797, 0.0]),
                (GeomKind::Cylinder, [0.2147914344804019, 0.3686548447814807, 0.0]),
                (GeomKind::Ellipsoid, [0.20441064831216976, 0.22517222064863399, 0.3686548447814807]),
                (GeomKind::Box, [0.20441064831216976, 0.22517222064863399, 0.3686548447814807]),
            ],
        );
        let bounding_box = (
            [0.15625, 0.15624999999999992, 0.1875],
            [
                (GeomKind::Sphere, [0.4419417382415935, 0.0, 0.0]),
                (GeomKind::Capsule, [0.2762135864009959, 0.16572815184059758, 0.0]),
                (GeomKind::Cylinder, [0.2762135864009959, 0.4419417382415935, 0.0]),
                (GeomKind::Ellipsoid, [0.2762135864009959, 0.2343750000000007, 0.4419417382415935]),
                (GeomKind::Box, [0.2762135864009959, 0.2343750000000007, 0.4419417382415935]),
            ],
        );
        for (fit_aabb, (pos, sizes)) in [(false, inertia_box), (true, bounding_box)] {
            for (kind, size) in sizes {
                let (fitted, center) = mesh.fit(kind, [0.0; 3], fit_aabb, 1.25).unwrap();
                assert!((0..3).all(|k| (fitted[k] - size[k]).abs() <= 1e-12 * size[0]), "{kind:?} {fitted:?}");
                let at = mesh.frame_point(&center);
                assert!((0..3).all(|k| (at[k] - pos[k]).abs() <= 1e-12), "{kind:?} at {at:?}");
            }
        }
        assert_eq!(mesh.fit(GeomKind::Plane, [1.0; 3], false, 1.0), None);
    }
}
