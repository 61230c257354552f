//! The contacts MuJoCo would make at the initial pose, which nudyn does not
//! model: each pair of geoms found gets a warning, so that a file whose
//! bodies touch does not export silently.
//!
//! What is checked, per pair of geoms (at qpos0, where the file puts the
//! bodies), after MuJoCo's filters: not in the same body nor in bodies
//! welded together; not a body and its parent's (`<flag filterparent>`,
//! unless disabled), the world aside; `contype` of one and `conaffinity` of
//! the other sharing a bit; not excluded by a `<contact><exclude>`. The
//! geoms then touch when their bounding spheres (MuJoCo's `geom_rbound`; a
//! mesh's: that of its bounding box), or a sphere and a plane's half space,
//! are closer than the larger of their margins. For spheres and planes that
//! is MuJoCo's own test; other shapes may be reported when only their
//! bounding spheres touch. Meshes that are not read (see
//! [`super::mesh::MeshAsset`]), height fields and sdfs are left out, as are
//! the `<contact><pair>`s a file adds.

use crate::math::{Quat, Vec3};

/// How far a geom reaches, in its frame.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Reach {
    /// The sphere around the frame's origin of this radius.
    Sphere(f64),
    /// The half space below the frame's xy plane.
    Plane,
}

/// A geom that may collide.
#[derive(Clone, Debug)]
pub(crate) struct ContactGeom {
    /// Its body (`None`: the world).
    pub body: Option<usize>,
    /// Its frame in the body, where `reach` is centred.
    pub pos: Vec3,
    pub quat: Quat,
    pub reach: Reach,
    /// `contype`, `conaffinity`.
    pub contype: i32,
    pub conaffinity: i32,
    pub margin: f64,
    /// The element as messages show it, and its line.
    pub label: String,
    pub line: u32,
}

/// What the bodies tell about which geoms MuJoCo collides.
pub(crate) struct BodyFilter<'a> {
    /// Each body's parent (`None`: the world).
    pub parents: &'a [Option<usize>],
    /// Each body's pose in the world at qpos0.
    pub poses: &'a [(Vec3, Quat)],
    /// Whether each body has joints or is a mocap body (MuJoCo's own weld root).
    pub roots: &'a [bool],
    /// `<flag filterparent>` is on.
    pub filter_parent: bool,
    /// The body pairs a `<contact><exclude>` names.
    pub excluded: &'a [(Option<usize>, Option<usize>)],
}

impl BodyFilter<'_> {
    /// The body a body is welded to (MuJoCo's `body_weldid`; `None`: the world).
    fn weld(&self, body: Option<usize>) -> Option<usize> {
        let mut body = body;
        while let Some(b) = body {
            if self.roots[b] {
                return Some(b);
            }
            body = self.parents[b];
        }
        None
    }

    /// MuJoCo's `filterBodyPair`, and the exclusions.
    fn filtered(&self, a: Option<usize>, b: Option<usize>) -> bool {
        let (weld_a, weld_b) = (self.weld(a), self.weld(b));
        if weld_a == weld_b || self.excluded.iter().any(|&pair| pair == (a, b) || pair == (b, a)) {
            return true;
        }
        let weld_parent = |weld: usize| self.weld(self.parents[weld]);
        match (weld_a, weld_b) {
            (Some(wa), Some(wb)) if self.filter_parent => weld_parent(wb) == Some(wa) || weld_parent(wa) == Some(wb),
            _ => false,
        }
    }

    /// A geom's frame in the world.
    fn place(&self, geom: &ContactGeom) -> (Vec3, Quat) {
        match geom.body {
            Some(body) => {
                let (pos, quat) = self.poses[body];
                (pos + quat * geom.pos, quat * geom.quat)
            }
            None => (geom.pos, geom.quat),
        }
    }
}

/// The pairs of geoms, by index, that MuJoCo would collide at qpos0, in
/// order. Spheres are swept along x (sorted by their lowest x, each
/// compared only with those starting before it ends), so that a file of
/// many bodies is not checked pair by pair.
pub(crate) fn touching(geoms: &[ContactGeom], bodies: &BodyFilter) -> Vec<(usize, usize)> {
    let placed: Vec<(Vec3, Quat)> = geoms.iter().map(|g| bodies.place(g)).collect();
    let largest_margin = geoms.iter().map(|g| g.margin).fold(0.0, f64::max);
    let mut spheres: Vec<(usize, f64)> = Vec::new();
    let mut planes = Vec::new();
    for (index, geom) in geoms.iter().enumerate() {
        match geom.reach {
            Reach::Sphere(radius) => spheres.push((index, radius)),
            Reach::Plane => planes.push(index),
        }
    }
    let lowest_x = |&(index, radius): &(usize, f64)| placed[index].0.x - radius;
    spheres.sort_by(|a, b| lowest_x(a).total_cmp(&lowest_x(b)));
    let mut pairs = Vec::new();
    let mut consider = |i: usize, j: usize, gap: f64| {
        let (a, b) = (&geoms[i], &geoms[j]);
        let affine = (a.contype & b.conaffinity) != 0 || (b.contype & a.conaffinity) != 0;
        if affine && a.body != b.body && gap < a.margin.max(b.margin) && !bodies.filtered(a.body, b.body) {
            pairs.push((i.min(j), i.max(j)));
        }
    };
    for (k, &(i, ri)) in spheres.iter().enumerate() {
        let end = placed[i].0.x + ri + largest_margin;
        for &(j, rj) in spheres[k + 1..].iter().take_while(|sphere| lowest_x(sphere) <= end) {
            consider(i, j, (placed[i].0 - placed[j].0).norm() - ri - rj);
        }
        for &plane in &planes {
            consider(plane, i, above(&placed[plane], &placed[i].0) - ri);
        }
    }
    pairs.sort_unstable();
    pairs
}

/// How far `point` is above the plane of the frame `plane` (along its z axis).
fn above(plane: &(Vec3, Quat), point: &Vec3) -> f64 {
    (plane.1 * Vec3::z()).dot(&(point - plane.0))
}

/// A geom's bounding radius (MuJoCo's `geom_rbound`) from its size.
pub(crate) fn bounding_radius(kind: super::defaults::GeomKind, size: &[f64; 3]) -> Option<f64> {
    use super::defaults::GeomKind;
    let [a, b, c] = *size;
    match kind {
        GeomKind::Sphere => Some(a),
        GeomKind::Capsule => Some(a + b),
        GeomKind::Cylinder => Some(a.hypot(b)),
        GeomKind::Ellipsoid => Some(a.max(b).max(c)),
        GeomKind::Box => Some((a * a + b * b + c * c).sqrt()),
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => None,
    }
}
