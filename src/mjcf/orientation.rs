//! MJCF's five ways of writing an orientation, resolved the way MuJoCo's
//! compiler resolves them.

use nalgebra::Quaternion;

use super::element::Element;
use super::error::MjcfError;
use crate::math::{Quat, Vec3, normalize_wxyz};

/// MuJoCo's `mjEPS`: squared norms below it count as zero.
const EPS: f64 = 1e-14;

/// MuJoCo's `mjMINVAL`: its kinematics take a quaternion of smaller norm
/// for the identity.
const MIN_QUATERNION_NORM: f64 = 1e-15;

/// The attributes that give an orientation; an element may use one of them.
pub(crate) const ORIENTATION_ATTRIBUTES: [&str; 5] = ["quat", "axisangle", "xyaxes", "zaxis", "euler"];

/// How `<compiler>` says angles are written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AngleConvention {
    /// `angle="degree"` (MuJoCo's default) rather than radians.
    pub degrees: bool,
    /// `eulerseq`: lowercase axes rotate with the frame, uppercase are fixed.
    pub euler_seq: [u8; 3],
}

impl AngleConvention {
    /// An angle in radians.
    pub fn radians(&self, angle: f64) -> f64 {
        if self.degrees { angle / 180.0 * std::f64::consts::PI } else { angle }
    }
}

/// An orientation as written in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Orientation {
    /// `quat="w x y z"`, normalized.
    Quat([f64; 4]),
    /// `axisangle="x y z angle"`.
    AxisAngle([f64; 4]),
    /// `xyaxes="x0 x1 x2 y0 y1 y2"`.
    XyAxes([f64; 6]),
    /// `zaxis="x y z"`: the minimal rotation taking (0, 0, 1) there.
    ZAxis([f64; 3]),
    /// `euler="a b c"` in the compiler's sequence.
    Euler([f64; 3]),
}

impl Default for Orientation {
    fn default() -> Self {
        Orientation::Quat([1.0, 0.0, 0.0, 0.0])
    }
}

impl Orientation {
    /// The element's orientation attribute, if it has one; two are an error.
    pub fn read(element: &Element) -> Result<Option<Orientation>, MjcfError> {
        let mut given = ORIENTATION_ATTRIBUTES.iter().filter(|a| element.has(a));
        if let (Some(first), Some(second)) = (given.next(), given.next()) {
            return Err(element.conflict(first, second));
        }
        if let Some(q) = element.numbers::<4>("quat")? {
            let mut unit = q;
            match normalize_wxyz(&mut unit) {
                None => return Err(element.bad_value("quat", "4 numbers that are not all zero")),
                // MuJoCo's kinematics replace a quaternion this short by the identity.
                Some(norm) if norm < MIN_QUATERNION_NORM => {
                    return Err(element.bad_value(
                        "quat",
                        "a quaternion of norm at least 1e-15 (MuJoCo would take a shorter one for the identity)",
                    ));
                }
                Some(_) => return Ok(Some(Orientation::Quat(unit))),
            }
        }
        if let Some(v) = element.numbers::<4>("axisangle")? {
            return Ok(Some(Orientation::AxisAngle(v)));
        }
        if let Some(v) = element.numbers::<6>("xyaxes")? {
            return Ok(Some(Orientation::XyAxes(v)));
        }
        if let Some(v) = element.numbers::<3>("zaxis")? {
            return Ok(Some(Orientation::ZAxis(v)));
        }
        Ok(element.numbers::<3>("euler")?.map(Orientation::Euler))
    }

    /// The unit quaternion, or why the vectors given cannot define one.
    pub fn resolve(&self, angles: &AngleConvention) -> Result<Quat, &'static str> {
        let q = match *self {
            Orientation::Quat([w, x, y, z]) => Quaternion::new(w, x, y, z),
            Orientation::AxisAngle([x, y, z, angle]) => {
                let axis = normalized(Vec3::new(x, y, z)).ok_or("the axis of 'axisangle' is too small")?;
                let half = angles.radians(angle) / 2.0;
                Quaternion::from_parts(half.cos(), axis * half.sin())
            }
            Orientation::XyAxes([x0, x1, x2, y0, y1, y2]) => {
                // Gram-Schmidt: y loses its component along x, z = x × y.
                let x = normalized(Vec3::new(x0, x1, x2)).ok_or("the x axis of 'xyaxes' is too small")?;
                let y = Vec3::new(y0, y1, y2);
                let y = normalized(y - x * x.dot(&y))
                    .ok_or("the y axis of 'xyaxes' is too small or parallel to the x axis")?;
                let z = normalized(x.cross(&y)).ok_or("the axes of 'xyaxes' do not span a plane")?;
                frame_to_quaternion(&x, &y, &z)
            }
            Orientation::ZAxis([x, y, z]) => {
                let axis = normalized(Vec3::new(x, y, z)).ok_or("'zaxis' is too small")?;
                z_to_quaternion(&axis)
            }
            Orientation::Euler(euler) => {
                let mut q = Quaternion::identity();
                for (&axis, angle) in angles.euler_seq.iter().zip(euler) {
                    let half = angles.radians(angle) / 2.0;
                    let unit = match axis.to_ascii_lowercase() {
                        b'x' => Vec3::x(),
                        b'y' => Vec3::y(),
                        _ => Vec3::z(),
                    };
                    let rotation = Quaternion::from_parts(half.cos(), unit * half.sin());
                    // Rotating axes compose on the right, fixed axes on the left.
                    q = if axis.is_ascii_lowercase() { q * rotation } else { rotation * q };
                }
                q
            }
        };
        Ok(Quat::new_normalize(q))
    }
}

/// `v` scaled to unit length, or `None` when its squared norm is below
/// mjEPS. Divided by its largest component first, so that components near
/// 1e±160 neither underflow nor overflow when squared.
pub(crate) fn normalized(v: Vec3) -> Option<Vec3> {
    let largest = v.amax();
    if largest == 0.0 {
        return None;
    }
    let scaled = v / largest;
    let scaled_norm = scaled.norm();
    (largest * scaled_norm >= EPS.sqrt()).then(|| scaled / scaled_norm)
}

/// MuJoCo's minimal rotation taking (0, 0, 1) to the unit vector `v`
/// (half a turn about x when `v` is -z).
pub(crate) fn z_to_quaternion(v: &Vec3) -> Quaternion<f64> {
    let cross = Vec3::z().cross(v);
    let (sin, axis) = match normalized(cross) {
        Some(axis) => (cross.norm(), axis),
        None => (0.0, Vec3::x()),
    };
    let half = sin.atan2(v.z) / 2.0;
    Quaternion::from_parts(half.cos(), axis * half.sin())
}

/// The quaternion of the frame with axes `x`, `y`, `z` (MuJoCo's
/// `mjuu_frame2quat`, which fixes the sign of the result).
fn frame_to_quaternion(x: &Vec3, y: &Vec3, z: &Vec3) -> Quaternion<f64> {
    // m[c][r]: row r of column c.
    let m = [x, y, z];
    let trace = m[0][0] + m[1][1] + m[2][2];
    if trace > 0.0 {
        let w = 0.5 * (1.0 + trace).sqrt();
        Quaternion::new(
            w,
            0.25 * (m[1][2] - m[2][1]) / w,
            0.25 * (m[2][0] - m[0][2]) / w,
            0.25 * (m[0][1] - m[1][0]) / w,
        )
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let qx = 0.5 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        Quaternion::new(
            0.25 * (m[1][2] - m[2][1]) / qx,
            qx,
            0.25 * (m[1][0] + m[0][1]) / qx,
            0.25 * (m[2][0] + m[0][2]) / qx,
        )
    } else if m[1][1] > m[2][2] {
        let qy = 0.5 * (1.0 - m[0][0] + m[1][1] - m[2][2]).sqrt();
        Quaternion::new(
            0.25 * (m[2][0] - m[0][2]) / qy,
            0.25 * (m[1][0] + m[0][1]) / qy,
            qy,
            0.25 * (m[2][1] + m[1][2]) / qy,
        )
    } else {
        let qz = 0.5 * (1.0 - m[0][0] - m[1][1] + m[2][2]).sqrt();
        Quaternion::new(
            0.25 * (m[0][1] - m[1][0]) / qz,
            0.25 * (m[2][0] + m[0][2]) / qz,
            0.25 * (m[2][1] + m[1][2]) / qz,
            qz,
        )
    }
}
