//! Mass properties of primitive geoms and of bodies, computed with MuJoCo's
//! formulas (`mjCGeom::SetInertia`, `mjCBody::InertiaFromGeom`).

use std::f64::consts::PI;

use nalgebra::SymmetricEigen;

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
    /// The orientation of the principal axes as the file gives it (MuJoCo's
    /// `body_iquat`); `None` when the axes come from an eigen-decomposition,
    /// whose order and signs are nalgebra's, not MuJoCo's.
    pub quat: Option<Quat>,
}

impl BodyInertia {
    /// From principal moments along the axes of the frame `quat`.
    pub fn from_principal(mass: f64, com: Vec3, quat: &Quat, principal: Vec3) -> Self {
        let axes = quat.to_rotation_matrix().into_inner();
        let tensor = axes * Mat3::from_diagonal(&principal) * axes.transpose();
        Self { mass, com, principal, axes, tensor, quat: Some(*quat) }
    }

    /// From a full tensor; MuJoCo requires its eigenvalues to be at least mjEPS.
    pub fn from_tensor(mass: f64, com: Vec3, tensor: Mat3) -> Result<Self, &'static str> {
        let eigen = SymmetricEigen::new(tensor);
        if eigen.eigenvalues.min() < EPS {
            return Err("inertia must have positive eigenvalues");
        }
        Ok(Self { mass, com, principal: eigen.eigenvalues, axes: eigen.eigenvectors, tensor, quat: None })
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

    /// Scales mass and inertia (MuJoCo's `settotalmass`).
    pub fn scale(&mut self, factor: f64) {
        self.mass *= factor;
        self.principal *= factor;
        self.tensor *= factor;
    }
}
