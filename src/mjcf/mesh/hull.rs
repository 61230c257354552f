//! The convex hull of a mesh's vertices, for `inertia="convex"` and for
//! meshes given without faces.
//!
//! A hull is unique as a solid, so any correct one gives MuJoCo's integrals
//! (MuJoCo uses qhull); only its triangulation of coplanar facets differs,
//! which moves the integrals by rounding. The hull is built incrementally
//! with exact orientation tests (Shewchuk's adaptive predicates, from the
//! `robust` crate), so it never fails on nearly coplanar input. The hull
//! crates considered were `quickhull` (single precision), `chull` (panics
//! on degenerate input through unwraps, unmaintained) and `parry3d-f64`
//! (a whole collision library for one function).

use std::collections::HashSet;

use robust::{Coord3D, orient3d};

/// The hull's triangles as indices into `points`, oriented outwards; `None`
/// when all points lie in one plane.
pub(crate) fn convex_hull(points: &[[f64; 3]]) -> Option<Vec<[usize; 3]>> {
    let at = |i: usize| Coord3D { x: points[i][0], y: points[i][1], z: points[i][2] };
    // orient3d(a, b, c, d) < 0: d lies on the side the normal (b−a)×(c−a) points to.
    let above = |face: &[usize; 3], p: usize| orient3d(at(face[0]), at(face[1]), at(face[2]), at(p)) < 0.0;

    let first = 0;
    let second = (1..points.len()).find(|&i| points[i] != points[first])?;
    let (third, fourth) = (1..points.len()).find_map(|third| {
        let fourth = (1..points.len()).find(|&p| orient3d(at(first), at(second), at(third), at(p)) != 0.0)?;
        Some((third, fourth))
    })?;
    let (b, c) =
        if orient3d(at(first), at(second), at(third), at(fourth)) > 0.0 { (second, third) } else { (third, second) };
    let (a, d) = (first, fourth);
    let mut faces = vec![[a, b, c], [a, d, b], [b, d, c], [c, d, a]];

    let simplex = [a, b, c, d];
    for p in (0..points.len()).filter(|p| !simplex.contains(p)) {
        if !faces.iter().any(|f| above(f, p)) {
            continue;
        }
        let (visible, kept): (Vec<[usize; 3]>, Vec<[usize; 3]>) = faces.into_iter().partition(|f| above(f, p));
        let edges: HashSet<(usize, usize)> =
            visible.iter().flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])]).collect();
        faces = kept;
        // The horizon: edges of visible faces whose neighbour is not visible
        // (in the faces' order, so that the result does not vary by run).
        for f in &visible {
            for (u, v) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                if !edges.contains(&(v, u)) {
                    faces.push([u, v, p]);
                }
            }
        }
    }
    Some(faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signed_volume(points: &[[f64; 3]], faces: &[[usize; 3]]) -> f64 {
        faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| nalgebra::Vector3::from(points[i]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn cube_with_inner_and_face_points() {
        let mut points = Vec::new();
        for k in 0..8 {
            points.push([(k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64]);
        }
        points.extend([[0.5, 0.5, 0.5], [0.5, 0.5, 1.0], [0.0, 0.0, 0.0], [0.25, 1.0, 0.75]]);
        let faces = convex_hull(&points).unwrap();
        assert!((signed_volume(&points, &faces) - 1.0).abs() < 1e-15);
        let used: HashSet<usize> = faces.iter().flatten().copied().collect();
        assert!(used.iter().all(|&i| i < 8), "only corners are hull vertices: {used:?}");
    }

    #[test]
    fn flat_and_repeated_points_have_no_hull() {
        assert!(convex_hull(&[[0.0, 0.0, 0.0]; 5]).is_none());
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.3, 0.2, 0.0]];
        assert!(convex_hull(&flat).is_none());
    }
}
