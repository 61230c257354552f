//! Mass properties of primitive geoms and of bodies, computed with MuJoCo's
//! formulas (`mjCGeom::SetInertia`, `mjCBody::InertiaFromGeom`).

use std::f64::consts::PI;

use super::defaults::GeomKind;
use crate::math::{Mat3, Quat, Vec3};

/// MuJoCo's `mjEPS`.
pub(crate) const EPS: f64 = 1e-14;

/// Volume of a primitive geom with MuJoCo's `size` convention (half sizes,
/// radius then half length); zero for the others.
pub(crate) fn volume(kind: GeomKind, size: &[f64; 3]) -> f64 {
    let [a, b, c] = *size;
    match kind {
        GeomKind::Sphere => 4.0 * PI * a * a * a / 3.0,
        GeomKind::Capsule => PI * (a * a * 2.0 * b + 4.0 * a * a * a / 3.0),
        GeomKind::Cylinder => PI * a * a * 2.0 * b,
        GeomKind::Ellipsoid => 4.0 * PI * a * b * c / 3.0,
        GeomKind::Box => 8.0 * a * b * c,
        GeomKind::Plane | GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => 0.0,
    }
}

/// Principal moments of inertia about the centre of a solid primitive geom
/// of this mass, in the geom's frame.
pub(crate) fn principal_moments(kind: GeomKind, size: &[f64; 3], mass: f64) -> Vec3 {
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
    /// The orientation of the principal axes (MuJoCo's `body_iquat`), as
    /// the file gives it or as MuJoCo's eigen-solver finds it.
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
        let (principal, quat) = principal_axes(&tensor);
        if principal.min() < EPS {
            return Err("inertia must have positive eigenvalues");
        }
        let axes = quat.to_rotation_matrix().into_inner();
        Ok(Self { mass, com, principal, axes, tensor, quat })
    }

    /// Sums geoms (each of mass above mjEPS): total mass, their common centre
    /// of mass, and the parallel-axis sum of their inertias about it. Like
    /// MuJoCo, a single geom's frame and moments are copied as they are.
    pub fn from_geoms(geoms: &[GeomMass]) -> Result<Self, &'static str> {
        if let [geom] = geoms {
            return Ok(Self::from_principal(geom.mass, geom.pos, &geom.quat, geom.principal));
        }
        let mass: f64 = geoms.iter().map(|g| g.mass).sum();
        let com = geoms.iter().map(|g| g.mass * g.pos).sum::<Vec3>() / mass;
        let tensor = geoms
            .iter()
            .map(|g| {
                let rotation = g.quat.to_rotation_matrix().into_inner();
                let d = g.pos - com;
                rotation * Mat3::from_diagonal(&g.principal) * rotation.transpose()
                    + g.mass * (Mat3::from_diagonal_element(d.norm_squared()) - d * d.transpose())
            })
            .sum();
        Self::from_tensor(mass, com, tensor)
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
    /// tensor's axes and moments from MuJoCo's eigen-solver. Its Jacobi
    /// iterations stop with the axes right to about 1e-6 rad, so the
    /// arithmetic follows MuJoCo's step by step, for its very axes.
    pub fn merged(&self, other: &BodyInertia, pos: &Vec3, quat: &Quat) -> Result<Self, &'static str> {
        let frame = wxyz(quat);
        let moved = mat_vec(&quat_to_mat(&frame), &[other.com.x, other.com.y, other.com.z]);
        let other_com = [pos.x + moved[0], pos.y + moved[1], pos.z + moved[2]];
        let parts = [
            (self.mass, [self.com.x, self.com.y, self.com.z], wxyz(&self.quat)),
            (other.mass, other_com, mul_quat(&frame, &wxyz(&other.quat))),
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
            let d = [part_com[0] - com[0], part_com[1] - com[1], part_com[2] - com[2]];
            let offset = [
                part_mass * (d[1] * d[1] + d[2] * d[2]),
                part_mass * (d[0] * d[0] + d[2] * d[2]),
                part_mass * (d[0] * d[0] + d[1] * d[1]),
                -part_mass * d[0] * d[1],
                -part_mass * d[0] * d[2],
                -part_mass * d[1] * d[2],
            ];
            for k in 0..6 {
                total[k] += own[k] + offset[k];
            }
        }
        let [xx, yy, zz, xy, xz, yz] = total;
        let (principal, quat) = principal_axes(&Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz));
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

/// The principal moments (decreasing) and axes of a symmetric tensor as
/// MuJoCo 4.0's compiler finds them (`mjuu_eig3`: Jacobi rotations
/// accumulated in a quaternion until the off-diagonal entries are below
/// 4e-15 of the largest entry, then sorted by quarter turns), with its
/// arithmetic, so that the axes' order and signs, hence a body's inertial
/// frame (`body_iquat`), are MuJoCo's.
pub(crate) fn principal_axes(tensor: &Mat3) -> (Vec3, Quat) {
    let scale = tensor.amax();
    let tolerance = 4e-15 * scale;
    let mut matrix = [0.0; 9];
    for (k, entry) in matrix.iter_mut().enumerate() {
        *entry = tensor[(k / 3, k % 3)];
    }
    let mut quat = [1.0, 0.0, 0.0, 0.0];
    let mut moments = [0.0; 3];
    for _ in 0..500 {
        let axes = quat_to_mat(&quat);
        let d = mat_mul(&mat_mul(&transpose(&axes), &matrix), &axes);
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
        quat = mul_quat(&quat, &turn);
        normalize(&mut quat);
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
            quat = mul_quat(&quat, &turn);
            normalize(&mut quat);
        }
    }
    let [w, x, y, z] = quat;
    (Vec3::from(moments), Quat::new_unchecked(nalgebra::Quaternion::new(w, x, y, z)))
}

// MuJoCo's small-vector helpers (`user_util.cc`), whose rounding the
// eigen-solver's stopping rule is sensitive to. Matrices are row-major.

/// A unit quaternion as (w, x, y, z).
fn wxyz(q: &Quat) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

/// Normalizes unless the norm is within mjEPS of 1 (`mjuu_normvec`).
fn normalize(v: &mut [f64; 4]) {
    let norm = v.iter().map(|x| x * x).sum::<f64>();
    if norm < EPS {
        return;
    }
    let norm = norm.sqrt();
    if (norm - 1.0).abs() > EPS {
        v.iter_mut().for_each(|x| *x /= norm);
    }
}

/// `mjuu_mulquat`.
fn mul_quat(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    let mut q = [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ];
    normalize(&mut q);
    q
}

/// `mjuu_quat2mat`.
fn quat_to_mat(q: &[f64; 4]) -> [f64; 9] {
    if *q == [1.0, 0.0, 0.0, 0.0] {
        return [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    }
    let (q00, q01, q02, q03) = (q[0] * q[0], q[0] * q[1], q[0] * q[2], q[0] * q[3]);
    let (q11, q12, q13, q22, q23, q33) = (q[1] * q[1], q[1] * q[2], q[1] * q[3], q[2] * q[2], q[2] * q[3], q[3] * q[3]);
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

/// `mjuu_mulmat`.
fn mat_mul(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    let mut product = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            product[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
        }
    }
    product
}

/// `mjuu_transposemat`.
fn transpose(m: &[f64; 9]) -> [f64; 9] {
    [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]]
}

/// `mjuu_mulvecmat`: the matrix times the vector.
fn mat_vec(m: &[f64; 9], v: &[f64; 3]) -> [f64; 3] {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    ]
}

/// `mjuu_globalinertia`: principal moments along the axes of `quat` as the
/// entries xx, yy, zz, xy, xz, yz of the tensor.
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
