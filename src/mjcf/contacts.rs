//! The contacts MuJoCo would make at the initial pose, which nudyn does not
//! model: each pair of geoms found gets a warning, so that a file whose
//! bodies touch does not export silently.
//!
//! What is checked, per pair of geoms (at qpos0, where the file puts the
//! bodies), after MuJoCo's filters: not in the same body nor in bodies
//! welded together; not a body and its parent's (`<flag filterparent>`,
//! unless disabled), the world aside; `contype` of one and `conaffinity` of
//! the other sharing a bit; not excluded by a `<contact><exclude>`. The
//! geoms then touch when they are closer than the larger of their margins,
//! which is computed exactly for spheres, capsules and planes (infinite,
//! as MuJoCo's are). Boxes, cylinders, ellipsoids, meshes, height fields
//! and sdfs are left out (their contacts would need MuJoCo's collision
//! functions; a bounding sphere would warn of contacts MuJoCo does not
//! make), as are the `<contact><pair>`s a file adds.

use crate::math::{Quat, Vec3};

/// How far a geom reaches, in its frame.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Reach {
    /// The points within `radius` of the segment along the frame's z axis
    /// from -`half_length` to `half_length`: a capsule, or a sphere (no length).
    Capsule { radius: f64, half_length: f64 },
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
/// order. Capsules are swept along x (sorted by their lowest x, each
/// compared only with those starting before it ends), so that a file of
/// many bodies is not checked pair by pair.
pub(crate) fn touching(geoms: &[ContactGeom], bodies: &BodyFilter) -> Vec<(usize, usize)> {
    let placed: Vec<(Vec3, Quat)> = geoms.iter().map(|g| bodies.place(g)).collect();
    let largest_margin = geoms.iter().map(|g| g.margin).fold(0.0, f64::max);
    // Each capsule's segment ends in the world, and its radius.
    let mut capsules: Vec<(usize, [Vec3; 2], f64)> = Vec::new();
    let mut planes = Vec::new();
    for (index, geom) in geoms.iter().enumerate() {
        let (pos, quat) = placed[index];
        match geom.reach {
            Reach::Capsule { radius, half_length } => {
                let axis = quat * Vec3::z() * half_length;
                capsules.push((index, [pos - axis, pos + axis], radius));
            }
            Reach::Plane => planes.push(index),
        }
    }
    let lowest_x = |(_, ends, radius): &(usize, [Vec3; 2], f64)| ends[0].x.min(ends[1].x) - radius;
    capsules.sort_by(|a, b| lowest_x(a).total_cmp(&lowest_x(b)));
    let mut pairs = Vec::new();
    let mut consider = |i: usize, j: usize, gap: f64| {
        let (a, b) = (&geoms[i], &geoms[j]);
        let affine = (a.contype & b.conaffinity) != 0 || (b.contype & a.conaffinity) != 0;
        if affine && a.body != b.body && gap < a.margin.max(b.margin) && !bodies.filtered(a.body, b.body) {
            pairs.push((i.min(j), i.max(j)));
        }
    };
    for (k, &(i, ends, radius)) in capsules.iter().enumerate() {
        let end = ends[0].x.max(ends[1].x) + radius + largest_margin;
        for &(j, other, other_radius) in capsules[k + 1..].iter().take_while(|c| lowest_x(c) <= end) {
            consider(i, j, segment_distance(&ends, &other) - radius - other_radius);
        }
        for &plane in &planes {
            let height = above(&placed[plane], &ends[0]).min(above(&placed[plane], &ends[1]));
            consider(plane, i, height - radius);
        }
    }
    pairs.sort_unstable();
    pairs
}

/// The distance between two segments (Ericson, Real-Time Collision
/// Detection, 5.1.9).
fn segment_distance([p1, q1]: &[Vec3; 2], [p2, q2]: &[Vec3; 2]) -> f64 {
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.dot(&d1), d2.dot(&d2), d2.dot(&r));
    let (s, t) = if a <= f64::EPSILON && e <= f64::EPSILON {
        (0.0, 0.0)
    } else if a <= f64::EPSILON {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= f64::EPSILON {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denominator = a * e - b * b;
            let s = if denominator > 0.0 { ((b * f - c * e) / denominator).clamp(0.0, 1.0) } else { 0.0 };
            let t = (b * s + f) / e;
            if t < 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// How far `point` is above the plane of the frame `plane` (along its z axis).
fn above(plane: &(Vec3, Quat), point: &Vec3) -> f64 {
    (plane.1 * Vec3::z()).dot(&(point - plane.0))
}

/// How far a sphere or capsule reaches, from its size; `None` for the
/// shapes whose contacts need MuJoCo's own collision functions.
pub(crate) fn reach(kind: super::defaults::GeomKind, size: &[f64; 3]) -> Option<Reach> {
    use super::defaults::GeomKind;
    match kind {
        GeomKind::Sphere => Some(Reach::Capsule { radius: size[0], half_length: 0.0 }),
        GeomKind::Capsule => Some(Reach::Capsule { radius: size[0], half_length: size[1] }),
        GeomKind::Plane => Some(Reach::Plane),
        _ => None,
    }
}
