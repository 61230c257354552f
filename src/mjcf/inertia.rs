//! Mass properties of primitive geoms and of bodies, computed with MuJoCo's
//! formulas (`mjCGeom::SetInertia`, `mjCBody::InertiaFromGeom`), and
//! MuJoCo's principal axes (`mjuu_eig3`), in MuJoCo's order of operations
//! so that nearly equal moments resolve to MuJoCo's axes.

use std::f64::consts::PI;

use nalgebra::Quaternion;

use super::defaults::GeomKind;
use crate::math::{Mat3, Quat, Vec3};

/// MuJoCo's `mjEPS`.
pub(crate) const EPS: f64 = 1e-14;

/// Volume of a primitive geom with MuJoCo's `size` convention (half sizes,
/// radius then half length), or its surface area with `shell`; zero for the
/// others.
pub(crate) fn volume(kind: GeomKind, size: &[f64; 3], shell: bool) -> f64 {
    let [a, b, c] = *size;
    if shell {
        return surface_area(kind, size);
    }
    match kind {
        GeomKind::Sphere => 4.0 * PI * a * a * a / 3.0,
        GeomKind::Capsule => PI * (a * a * 2.0 * b + 4.0 * a * a * a / 3.0),
        GeomKind::Cylinder => PI * a * a * 2.0 * b,
        GeomKind::Ellipsoid => 4.0 * PI * a * b * c / 3.0,
        GeomKind::Box => 8.0 * a * b * c,
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => 0.0,
    }
}

/// Surface area of a primitive geom (MuJoCo's Thomsen approximation for
/// the ellipsoid).
fn surface_area(kind: GeomKind, size: &[f64; 3]) -> f64 {
    let [a, b, c] = *size;
    match kind {
        GeomKind::Sphere => 4.0 * PI * a * a,
        GeomKind::Capsule => 4.0 * PI * a * a + 2.0 * PI * a * (2.0 * b),
        GeomKind::Cylinder => 2.0 * PI * a * a + 2.0 * PI * a * (2.0 * b),
        GeomKind::Ellipsoid => {
            let p = 1.6075;
            let sum = (a * b).powf(p) + (b * c).powf(p) + (c * a).powf(p);
            4.0 * PI * (sum / 3.0).powf(1.0 / p)
        }
        GeomKind::Box => 8.0 * (a * b + b * c + c * a),
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => 0.0,
    }
}

/// Principal moments of inertia about the centre of a primitive geom of
/// this mass, in the geom's frame: of the solid, or with `shell` of its
/// surface (MuJoCo's `shellinertia`).
pub(crate) fn principal_moments(kind: GeomKind, size: &[f64; 3], mass: f64, shell: bool) -> Vec3 {
    if shell {
        return shell_moments(kind, size, mass);
    }
    let [a, b, c] = *size;
    match kind {
        GeomKind::Sphere => Vec3::repeat(2.0 * mass * a * a / 5.0),
        GeomKind::Capsule => {
            // A cylinder plus two hemispheres, each moved along z; MuJoCo's own
            // expression for the hemispheres' offset term.
            let (radius, height) = (a, 2.0 * b);
            let sphere_mass = mass * 4.0 * radius / (4.0 * radius + 3.0 * height);
            let cylinder_mass = mass - sphere_mass;
            let sphere_inertia = 2.0 * sphere_mass * radius * radius / 5.0;
            let transverse = cylinder_mass * (3.0 * radius * radius + height * height) / 12.0
                + sphere_inertia
                + sphere_mass * height * (3.0 * radius + 2.0 * height) / 8.0;
            let axial = cylinder_mass * radius * radius / 2.0 + sphere_inertia;
            Vec3::new(transverse, transverse, axial)
        }
        GeomKind::Cylinder => {
            let (radius, height) = (a, 2.0 * b);
            let transverse = mass * (3.0 * radius * radius + height * height) / 12.0;
            Vec3::new(transverse, transverse, mass * radius * radius / 2.0)
        }
        GeomKind::Ellipsoid => {
            Vec3::new(mass * (b * b + c * c) / 5.0, mass * (a * a + c * c) / 5.0, mass * (a * a + b * b) / 5.0)
        }
        GeomKind::Box => {
            Vec3::new(mass * (b * b + c * c) / 3.0, mass * (a * a + c * c) / 3.0, mass * (a * a + b * b) / 3.0)
        }
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => Vec3::zeros(),
    }
}

/// Principal moments of a primitive's surface of this mass, with MuJoCo's
/// decompositions (hemispheres and a tube; disks and a tube; six plates; the
/// ellipsoid as the difference of two solids 1e-6 apart).
fn shell_moments(kind: GeomKind, size: &[f64; 3], mass: f64) -> Vec3 {
    let [a, b, c] = *size;
    match kind {
        GeomKind::Sphere => Vec3::repeat(2.0 * mass * a * a / 3.0),
        GeomKind::Capsule => {
            let (radius, half_height, height) = (a, b, 2.0 * b);
            let sphere_area = 4.0 * PI * radius * radius;
            let total_area = sphere_area + 2.0 * PI * radius * height;
            let sphere_mass = mass * sphere_area / total_area;
            let cylinder_mass = mass - sphere_mass;
            let sphere_inertia = 2.0 * sphere_mass * radius * radius / 3.0;
            let (hemisphere_com, hemisphere_pos) = (radius / 2.0, half_height + radius / 2.0);
            let transverse = cylinder_mass * (6.0 * radius * radius + height * height) / 12.0
                + sphere_inertia
                + sphere_mass * (hemisphere_pos * hemisphere_pos - hemisphere_com * hemisphere_com);
            Vec3::new(transverse, transverse, cylinder_mass * radius * radius + sphere_inertia)
        }
        GeomKind::Cylinder => {
            let (radius, half_height, height) = (a, b, 2.0 * b);
            let disk_area = PI * radius * radius;
            let total_area = 2.0 * disk_area + 2.0 * PI * radius * height;
            let disk_mass = mass * disk_area / total_area;
            let tube_mass = mass - 2.0 * disk_mass;
            let disk_transverse = disk_mass * radius * radius / 4.0 + disk_mass * half_height * half_height;
            let disk_axial = disk_mass * radius * radius / 2.0;
            let transverse = tube_mass * (6.0 * radius * radius + height * height) / 12.0 + 2.0 * disk_transverse;
            Vec3::new(transverse, transverse, tube_mass * radius * radius + 2.0 * disk_axial)
        }
        GeomKind::Ellipsoid => {
            let eps = 1e-6;
            let inner_volume = 4.0 * PI * a * b * c / 3.0;
            let (ae, be, ce) = (a + eps, b + eps, c + eps);
            let outer_volume = 4.0 * PI * ae * be * ce / 3.0;
            let density = mass / (outer_volume - inner_volume);
            let (inner, outer) = (inner_volume * density, outer_volume * density);
            Vec3::new(
                outer * (be * be + ce * ce) / 5.0 - inner * (b * b + c * c) / 5.0,
                outer * (ae * ae + ce * ce) / 5.0 - inner * (a * a + c * c) / 5.0,
                outer * (ae * ae + be * be) / 5.0 - inner * (a * a + b * b) / 5.0,
            )
        }
        GeomKind::Box => {
            let (lx, ly, lz) = (2.0 * a, 2.0 * b, 2.0 * c);
            let (area_xy, area_yz, area_zx) = (lx * ly, ly * lz, lz * lx);
            let total_area = 2.0 * (area_xy + area_yz + area_zx);
            let (m0, m1, m2) = (mass * area_xy / total_area, mass * area_yz / total_area, mass * area_zx / total_area);
            let (ix0, iy0, iz0) = (m0 * ly * ly / 12.0, m0 * lx * lx / 12.0, m0 * (lx * lx + ly * ly) / 12.0);
            let (ix1, iy1, iz1) = (m1 * (ly * ly + lz * lz) / 12.0, m1 * lz * lz / 12.0, m1 * ly * ly / 12.0);
            let (ix2, iy2, iz2) = (m2 * lz * lz / 12.0, m2 * (lx * lx + lz * lz) / 12.0, m2 * lx * lx / 12.0);
            let (s00, s11, s22) = (a * a, b * b, c * c);
            Vec3::new(
                2.0 * (m0 * s22 + m2 * s11 + ix0 + ix1 + ix2),
                2.0 * (m0 * s22 + m1 * s00 + iy0 + iy1 + iy2),
                2.0 * (m1 * s00 + m2 * s11 + iz0 + iz1 + iz2),
            )
        }
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => Vec3::zeros(),
    }
}

/// A geom's contribution to its body: mass, and principal moments about its
/// centre `pos` along the axes of its frame `quat` (both in the body frame).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GeomMass {
    /// Mass.
    pub mass: f64,
    /// Centre in the body frame.
    pub pos: Vec3,
    /// Orientation of the geom frame in the body frame.
    pub quat: Quat,
    /// Principal moments in the geom frame.
    pub principal: Vec3,
}

/// A body's mass properties in MuJoCo's form (principal moments along
/// principal axes) together with the tensor they make.
#[derive(Clone, Debug)]
pub(crate) struct BodyInertia {
    /// Mass.
    pub mass: f64,
    /// Centre of mass in the body frame.
    pub com: Vec3,
    /// Principal moments.
    pub principal: Vec3,
    /// Principal axes in the body frame (columns, matching `principal`).
    pub axes: Mat3,
    /// Inertia tensor about the centre of mass, in body axes.
    pub tensor: Mat3,
    /// The orientation of the principal axes (MuJoCo's `body_iquat`): as the
    /// file gives it, or from MuJoCo's own eigen-decomposition.
    pub quat: Quat,
}

impl BodyInertia {
    /// From principal moments along the axes of the frame `quat`.
    pub fn from_principal(mass: f64, com: Vec3, quat: &Quat, principal: Vec3) -> Self {
        let axes = quat.to_rotation_matrix().into_inner();
        let tensor = axes * Mat3::from_diagonal(&principal) * axes.transpose();
        Self { mass, com, principal, axes, tensor, quat: *quat }
    }

    /// From a full tensor, with the principal moments and axes MuJoCo's
    /// eigen-solver finds (its order and signs); MuJoCo requires the
    /// moments to be at least mjEPS.
    pub fn from_tensor(mass: f64, com: Vec3, tensor: Mat3) -> Result<Self, &'static str> {
        let (principal, quat) = principal_axes(&tensor, Eigen::Body);
        if principal.min() < EPS {
            return Err("inertia must have positive eigenvalues");
        }
        let axes = quat.to_rotation_matrix().into_inner();
        Ok(Self { mass, com, principal, axes, tensor, quat })
    }

    /// Sums geoms (each of mass above mjEPS): total mass, their common centre
    /// of mass, and the parallel-axis sum of their inertias about it, in
    /// MuJoCo's arithmetic. Like MuJoCo, a single geom's frame and moments
    /// are copied as they are.
    pub fn from_geoms(geoms: &[GeomMass]) -> Result<Self, &'static str> {
        if let [geom] = geoms {
            return Ok(Self::from_principal(geom.mass, geom.pos, &geom.quat, geom.principal));
        }
        let mut mass = 0.0;
        let mut weighted = [0.0; 3];
        for g in geoms {
            mass += g.mass;
            for (sum, x) in weighted.iter_mut().zip(g.pos.iter()) {
                *sum += g.mass * x;
            }
        }
        if mass < EPS {
            return Err("body mass is too small, cannot compute center of mass");
        }
        let com = weighted.map(|w| w / mass);
        let mut total = [0.0; 6];
        for g in geoms {
            let rotated = global_inertia(&g.principal.into(), &quat_array(&g.quat));
            let offset = off_center(g.mass, &[g.pos[0] - com[0], g.pos[1] - com[1], g.pos[2] - com[2]]);
            for j in 0..6 {
                total[j] = total[j] + rotated[j] + offset[j];
            }
        }
        let [xx, yy, zz, xy, xz, yz] = total;
        Self::from_tensor(mass, Vec3::from(com), Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz))
    }

    /// Replaces the principal moments, keeping the axes.
    pub fn set_principal(&mut self, principal: Vec3) {
        self.principal = principal;
        self.tensor = self.axes * Mat3::from_diagonal(&principal) * self.axes.transpose();
    }

    /// Moves the mass properties, given in a frame at `pos` and `quat` in the
    /// body frame, into the body frame.
    pub fn place(&mut self, pos: &Vec3, quat: &Quat) {
        let rotation = quat.to_rotation_matrix().into_inner();
        self.com = pos + rotation * self.com;
        self.axes = rotation * self.axes;
        self.tensor = rotation * self.tensor * rotation.transpose();
        self.quat = quat * self.quat;
    }

    /// These mass properties with `other`'s, given in a frame at `pos` and
    /// `quat` in this body's frame, added as MuJoCo's
    /// `mjCBody::AccumulateInertia` adds them for `fusestatic`: the summed
    /// tensor's axes and moments from MuJoCo's eigen-solver, with the
    /// arithmetic following MuJoCo's step by step, for its very axes.
    pub fn merged(&self, other: &BodyInertia, pos: &Vec3, quat: &Quat) -> Result<Self, &'static str> {
        let frame = quat_array(quat);
        let moved = mat_vec(&quat_to_mat(&frame), &[other.com.x, other.com.y, other.com.z]);
        let other_com = [pos.x + moved[0], pos.y + moved[1], pos.z + moved[2]];
        let parts = [
            (self.mass, [self.com.x, self.com.y, self.com.z], quat_array(&self.quat)),
            (other.mass, other_com, mul_quat(&frame, &quat_array(&other.quat))),
        ];
        let mass = 0.0 + parts[0].0 + parts[1].0;
        // MuJoCo's mjMINVAL.
        if mass < 1e-15 {
            return Ok(Self::from_principal(0.0, Vec3::zeros(), &Quat::identity(), Vec3::zeros()));
        }
        let mut com = [0.0; 3];
        for (part_mass, part_com, ..) in &parts {
            for k in 0..3 {
                com[k] += part_mass * part_com[k];
            }
        }
        let com = com.map(|c| c / mass);
        // Entries xx, yy, zz, xy, xz, yz.
        let mut total = [0.0; 6];
        for ((part_mass, part_com, part_quat), part) in parts.iter().zip([self, other]) {
            let own = global_inertia(&[part.principal.x, part.principal.y, part.principal.z], part_quat);
            let offset = off_center(*part_mass, &[part_com[0] - com[0], part_com[1] - com[1], part_com[2] - com[2]]);
            for k in 0..6 {
                total[k] += own[k] + offset[k];
            }
        }
        let [xx, yy, zz, xy, xz, yz] = total;
        let (principal, quat) = principal_axes(&Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz), Eigen::Body);
        if principal.min() < EPS {
            return Err("inertia must have positive eigenvalues");
        }
        Ok(Self::from_principal(mass, Vec3::from(com), &quat, principal))
    }

    /// Scales mass and inertia (MuJoCo's `settotalmass`).
    pub fn scale(&mut self, factor: f64) {
        self.mass *= factor;
        self.principal *= factor;
        self.tensor *= factor;
    }
}

/// A quaternion as MuJoCo stores it: w, x, y, z.
pub(crate) fn quat_array(quat: &Quat) -> [f64; 4] {
    [quat.w, quat.i, quat.j, quat.k]
}

/// MuJoCo's `mjuu_quat2mat`: the rotation matrix, row-major.
pub(crate) fn quat_to_mat(q: &[f64; 4]) -> [f64; 9] {
    if *q == [1.0, 0.0, 0.0, 0.0] {
        return [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    }
    let (q00, q01, q02, q03) = (q[0] * q[0], q[0] * q[1], q[0] * q[2], q[0] * q[3]);
    let (q11, q12, q13) = (q[1] * q[1], q[1] * q[2], q[1] * q[3]);
    let (q22, q23, q33) = (q[2] * q[2], q[2] * q[3], q[3] * q[3]);
    [
        q00 + q11 - q22 - q33,
        2.0 * (q12 - q03),
        2.0 * (q13 + q02),
        2.0 * (q12 + q03),
        q00 - q11 + q22 - q33,
        2.0 * (q23 - q01),
        2.0 * (q13 - q02),
        2.0 * (q23 + q01),
        q00 - q11 - q22 + q33,
    ]
}

/// MuJoCo's `mjuu_mulquat`: the normalized product.
pub(crate) fn mul_quat(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    let product = [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ];
    normalize4(product)
}

/// MuJoCo's `mjuu_normvec` for a quaternion: left as it is when its squared
/// norm is below mjEPS or its norm within mjEPS of 1.
pub(crate) fn normalize4(q: [f64; 4]) -> [f64; 4] {
    let squared = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if squared < EPS {
        return q;
    }
    let norm = squared.sqrt();
    if (norm - 1.0).abs() > EPS { q.map(|x| x / norm) } else { q }
}

/// `a · b` for row-major 3×3 matrices.
fn mul_mat(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    let mut out = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
        }
    }
    out
}

/// MuJoCo's `mjuu_transposemat`.
fn transpose(m: &[f64; 9]) -> [f64; 9] {
    [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]]
}

/// MuJoCo's `mjuu_mulvecmat`: the matrix times the vector.
fn mat_vec(m: &[f64; 9], v: &[f64; 3]) -> [f64; 3] {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    ]
}

/// MuJoCo's `mjuu_globalinertia`: principal moments along the axes of
/// `quat` as a tensor (xx, yy, zz, xy, xz, yz).
fn global_inertia(local: &[f64; 3], quat: &[f64; 4]) -> [f64; 6] {
    let m = quat_to_mat(quat);
    let t = [
        m[0] * local[0],
        m[3] * local[0],
        m[6] * local[0],
        m[1] * local[1],
        m[4] * local[1],
        m[7] * local[1],
        m[2] * local[2],
        m[5] * local[2],
        m[8] * local[2],
    ];
    [
        m[0] * t[0] + m[1] * t[3] + m[2] * t[6],
        m[3] * t[1] + m[4] * t[4] + m[5] * t[7],
        m[6] * t[2] + m[7] * t[5] + m[8] * t[8],
        m[0] * t[1] + m[1] * t[4] + m[2] * t[7],
        m[0] * t[2] + m[1] * t[5] + m[2] * t[8],
        m[3] * t[2] + m[4] * t[5] + m[5] * t[8],
    ]
}

/// MuJoCo's `mjuu_offcenter`: the parallel-axis term of a point mass at `d`.
fn off_center(mass: f64, d: &[f64; 3]) -> [f64; 6] {
    [
        mass * (d[1] * d[1] + d[2] * d[2]),
        mass * (d[0] * d[0] + d[2] * d[2]),
        mass * (d[0] * d[0] + d[1] * d[1]),
        -mass * d[0] * d[1],
        -mass * d[0] * d[2],
        -mass * d[1] * d[2],
    ]
}

/// Which of MuJoCo 4.0's stopping rules the eigen-solver follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Eigen {
    /// A body's principal axes (`fullinertia`, several geoms, `fusestatic`):
    /// until the off-diagonal entries are below 4e-15 of the tensor's
    /// largest entry.
    Body,
    /// A mesh's frame: MuJoCo 4.0 stops while the largest off-diagonal entry
    /// is still near 1e-7 of the largest diagonal one. Its source was not at
    /// hand; the stop (below 9.5e-8) was fitted to its mesh frames, which it
    /// reproduces to 1e-9 on every fixture of tests/python/test_mesh_inertia.py
    /// and on 397 of 400 random tetrahedra (the four inertia modes; the
    /// others within 7e-8), where MuJoCo 3's rule missed about one in ten by
    /// up to 3e-6. The moments agree to rounding either way.
    Mesh,
}

/// The principal moments (decreasing) and axes of a symmetric tensor as
/// MuJoCo 4.0 finds them (`mjuu_eig3`: Jacobi rotations accumulated in a
/// quaternion until `kind`'s stop, then sorted by quarter turns), with its
/// arithmetic, so that the axes' order and signs, hence a body's inertial
/// frame (`body_iquat`) and a mesh's frame, are MuJoCo's. For bodies this
/// gives MuJoCo's `body_iquat` bit for bit on random full tensors scaled
/// from 1e-6 to 1e6, two nearly equal moments among them.
pub(crate) fn principal_axes(tensor: &Mat3, kind: Eigen) -> (Vec3, Quat) {
    const MESH_STOP: f64 = 9.5e-8;
    let scale = tensor.amax();
    let matrix: [f64; 9] = std::array::from_fn(|k| tensor[(k / 3, k % 3)]);
    let mut quat = [1.0, 0.0, 0.0, 0.0];
    let mut moments = [0.0; 3];
    for _ in 0..500 {
        let axes = quat_to_mat(&quat);
        let d = mul_mat(&mul_mat(&transpose(&axes), &matrix), &axes);
        moments = [d[0], d[4], d[8]];
        // The largest off-diagonal element (row, column) and the axis it turns about.
        let (row, column, axis) = if d[1].abs() > d[2].abs() && d[1].abs() > d[5].abs() {
            (0, 1, 2)
        } else if d[2].abs() > d[5].abs() {
            (0, 2, 1)
        } else {
            (1, 2, 0)
        };
        let off = d[3 * row + column];
        let tolerance = match kind {
            Eigen::Body => 4e-15 * scale,
            Eigen::Mesh => MESH_STOP * d[0].abs().max(d[4].abs()).max(d[8].abs()),
        };
        if off.abs() <= tolerance {
            break;
        }
        // The 2x2 symmetric Schur decomposition, as a turn about `axis`.
        let tau = (d[4 * column] - d[4 * row]) / (2.0 * off);
        let t =
            if tau >= 0.0 { 1.0 / (tau + (1.0 + tau * tau).sqrt()) } else { -1.0 / (-tau + (1.0 + tau * tau).sqrt()) };
        // The tangent of half the angle, for the turn's quaternion.
        let half = t / (1.0 + (1.0 + t * t).sqrt());
        let mut turn = [1.0 / (1.0 + half * half).sqrt(), 0.0, 0.0, 0.0];
        turn[axis + 1] = if axis == 1 { half } else { -half } * turn[0];
        quat = normalize4(mul_quat(&quat, &turn));
    }
    // Decreasing order, by quarter turns (bubble sort over the pairs 0, 1,
    // 0), leaving moments within 1e-12 of the largest entry as they are.
    let tie = 1e-12 * scale;
    for j in 0..3 {
        let lead = j % 2;
        if moments[lead] + tie < moments[lead + 1] {
            moments.swap(lead, lead + 1);
            // MuJoCo's literal for cos(π/4), which differs from FRAC_1_SQRT_2 in the last bits.
            #[allow(clippy::approx_constant)]
            let mut turn = [0.707106781186548, 0.0, 0.0, 0.0];
            turn[(lead + 2) % 3 + 1] = turn[0];
            quat = normalize4(mul_quat(&quat, &turn));
        }
    }
    let [w, x, y, z] = quat;
    (Vec3::from(moments), Quat::new_unchecked(Quaternion::new(w, x, y, z)))
}
