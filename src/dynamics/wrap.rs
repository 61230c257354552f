//! A spatial tendon's segment wrapped around a sphere or a cylinder, with
//! MuJoCo's geometry (its `mju_wrap`, engine_util_misc.c): the segment
//! between two sites, seen in the geom's frame, is projected onto a plane
//! (through the sites and the sphere's centre; the cylinder's x-y plane),
//! wrapped around the circle there along the tangent lines from each site,
//! and, for a cylinder, lifted back along its axis as a helix, the shorter
//! way round. No wrap when the straight segment misses the circle. With a
//! side site, MuJoCo 4.0's rule (XML reference, `sidesite`): the shortest
//! path homotopic to the polyline from the first site through the side
//! site to the second, in the plane with the disc removed.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::math::{Real, Transform, Vec3};
use crate::model::WRAP_SWITCHES;

/// MuJoCo's `mjMINVAL`.
const MIN_VALUE: f64 = 1e-15;

/// A 2D point.
type Point<S> = [S; 2];

/// A wrap's arc length and the two points where the tendon meets the geom.
type Wrapped<S> = (S, Vec3<S>, Vec3<S>);

/// Which path a wrap takes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WrapPath {
    /// Straight from site to site.
    #[default]
    Straight,
    /// Round the geom: by the first or second pair of tangent points, or
    /// for a side site's wrap the signs of its turns (`wrap_circle_through`).
    Around(usize),
}

/// The wrap of `x0 → x1` (world points) around a sphere or cylinder of
/// `radius` placed at `geom` (world → geom frame): the path taken, and
/// the arc's length and the two points where the tendon meets the geom
/// (world), or `None` when it runs straight.
/// `side`: the side site (world), if any.
///
/// MuJoCo decides the path on the state; `held` takes a path decided
/// before instead, continued smoothly past where the state would decide
/// otherwise (an arc shrinking through zero goes on as a negative one),
/// as an integrator holds it over a step. `switching` gets the functions
/// whose signs decide the path, +∞ where one is not reached: whether the
/// segment meets the circle (the wrap comes on and off with zero arc, its
/// length once differentiable and its curvature unbounded there), whether
/// both sites are outside it (the path jumps to straight when one
/// enters), and which of the two ways round is taken (the moment arms
/// jump where they swap).
#[allow(clippy::too_many_arguments)]
pub(super) fn wrap<S: Real>(
    x0: &Vec3<S>,
    x1: &Vec3<S>,
    geom: &Transform<S>,
    radius: f64,
    cylinder: bool,
    side: Option<&Vec3<S>>,
    held: Option<WrapPath>,
    switching: &mut [f64; WRAP_SWITCHES],
) -> (WrapPath, Option<Wrapped<S>>) {
    *switching = [f64::INFINITY; WRAP_SWITCHES];
    let local = |x: &Vec3<S>| geom.rot * (x - geom.trans);
    let (p0, p1) = (local(x0), local(x1));
    if p0.norm().value() < MIN_VALUE || p1.norm().value() < MIN_VALUE {
        return (WrapPath::Straight, None);
    }
    let side = side.map(local);
    let (axis0, axis1) = if cylinder { (Vec3::x(), Vec3::y()) } else { sphere_plane(&p0, &p1, side.as_ref()) };
    let ends = [p0.dot(&axis0), p0.dot(&axis1), p1.dot(&axis0), p1.dot(&axis1)];
    let (path, wrapped) = match side {
        Some(s) => wrap_circle_through(&ends, [s.dot(&axis0), s.dot(&axis1)], radius, held, switching),
        None => wrap_circle(&ends, radius, held, switching),
    };
    let Some((length, points)) = wrapped else { return (path, None) };
    let lift = |k: usize| axis0 * points[2 * k] + axis1 * points[2 * k + 1];
    let (mut q0, mut q1) = (lift(0), lift(1));
    let mut length = length;
    if cylinder {
        // The helix: heights in proportion to the path length up to each point.
        let planar = |p: &Vec3<S>, q: &Vec3<S>| ((p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y)).sqrt();
        let (to_first, from_second) = (planar(&p0, &q0), planar(&p1, &q1));
        let total = to_first + length + from_second;
        q0.z = p0.z + (p1.z - p0.z) * to_first / total;
        q1.z = p0.z + (p1.z - p0.z) * (to_first + length) / total;
        let height = (q1.z - q0.z).abs();
        // Signed: a held arc continued through zero (never negative as MuJoCo decides it).
        let helix = (length * length + height * height).sqrt();
        length = if length.value() < 0.0 { -helix } else { helix };
    }
    let world = |q: &Vec3<S>| geom.rot.transpose() * q + geom.trans;

    (path, Some((length, world(&q0), world(&q1))))
}

/// The plane of a sphere wrap: its first axis towards `p0`, its second in
/// the plane of `p0`, `p1` and the centre (when the three are aligned, the
/// plane through the side site `side`, or any plane through `p0`, chosen as
/// MuJoCo chooses it).
fn sphere_plane<S: Real>(p0: &Vec3<S>, p1: &Vec3<S>, side: Option<&Vec3<S>>) -> (Vec3<S>, Vec3<S>) {
    let axis0 = normalized(p0);
    let mut normal = p0.cross(p1);
    if let Some(side) = side.filter(|_| normal.norm().value() < MIN_VALUE) {
        normal = p0.cross(side);
    }
    if normal.norm().value() < MIN_VALUE {
        let a = axis0.map(|x| x.value().abs());
        let largest = if a.y > a.x && a.y > a.z {
            1
        } else if a.z > a.x && a.z > a.y {
            2
        } else {
            0
        };
        let mut other = Vec3::from_element(S::one());
        other[largest] = S::zero();
        normal = axis0.cross(&other);
    }
    let normal = normalized(&normal);
    (axis0, normalized(&normal.cross(&axis0)))
}

/// MuJoCo's `mju_normalize3`: x along the unit x axis when it vanishes.
fn normalized<S: Real>(v: &Vec3<S>) -> Vec3<S> {
    let norm = v.norm();
    if norm.value() < MIN_VALUE { Vec3::x() } else { v * (S::one() / norm) }
}

/// MuJoCo's `mju_normalize` of a 2D vector.
fn normalize2<S: Real>(v: &mut Point<S>) -> S {
    let norm = (v[0] * v[0] + v[1] * v[1]).sqrt();
    if norm.value() < MIN_VALUE {
        *v = [S::one(), S::zero()];
    } else {
        let inverse = S::one() / norm;
        v[0] *= inverse;
        v[1] *= inverse;
    }
    norm
}

/// Whether the 2D segments a₁a₂ and b₁b₂ cross (parallel ones never do).
fn segments_cross<S: Real>(a1: &[S], a2: &[S], b1: &[S], b2: &[S]) -> bool {
    let [a1, a2, b1, b2] = [a1, a2, b1, b2].map(|p| [p[0].value(), p[1].value()]);
    let det = (b2[1] - b1[1]) * (a2[0] - a1[0]) - (b2[0] - b1[0]) * (a2[1] - a1[1]);
    if det.abs() < MIN_VALUE {
        return false;
    }
    let s = ((b2[0] - b1[0]) * (a1[1] - b1[1]) - (b2[1] - b1[1]) * (a1[0] - b1[0])) / det;
    let t = ((a2[0] - a1[0]) * (a1[1] - b1[1]) - (a2[1] - a1[1]) * (a1[0] - b1[0])) / det;
    (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t)
}

/// The arc from `p0` to `p1` on the circle of `radius`, the long way round
/// when the tangents' orientation says so (`second`: the second of the two
/// tangent solutions). `continued`: a held wrap past where its segment
/// stops meeting the circle, whose tangent points have crossed over: its
/// arc goes on through zero to a small negative one instead of jumping to
/// nearly a whole turn.
fn arc_length<S: Real>(p0: &Point<S>, p1: &Point<S>, second: bool, radius: f64, continued: bool) -> S {
    let (mut u0, mut u1) = (*p0, *p1);
    normalize2(&mut u0);
    normalize2(&mut u1);
    // MuJoCo's acos of the dot product, as atan2 of |cross| and dot: the same
    // angle, but acos near 1 keeps half the digits (an arc of 1e-8 rad reads
    // 0), where a wrap coming on starts.
    let mut angle = (u0[0] * u1[1] - u0[1] * u1[0]).abs().atan2_differentiable(u0[0] * u1[0] + u0[1] * u1[1]);
    let cross = (p0[1] * p1[0] - p0[0] * p1[1]).value();
    if (cross > 0.0 && second) || (cross < 0.0 && !second) {
        angle = if continued { -angle } else { -angle + 2.0 * PI };
    }
    angle * radius
}

/// The wrap around a circle of the 2D segment `ends` (x₀, y₀, x₁, y₁):
/// the path (`held`, or as the segment decides), and for a wrap the
/// arc's length and its end points (x, y, x, y); MuJoCo's is `None` when
/// a site is inside the circle or the segment does not cross it.
/// `switching` as [`wrap`]'s.
fn wrap_circle<S: Real>(
    ends: &[S; 4],
    radius: f64,
    held: Option<WrapPath>,
    switching: &mut [f64; WRAP_SWITCHES],
) -> (WrapPath, Option<(S, [S; 4])>) {
    let square0 = ends[0] * ends[0] + ends[1] * ends[1];
    let square1 = ends[2] * ends[2] + ends[3] * ends[3];
    let square_radius = radius * radius;
    switching[1] = square0.value().min(square1.value()) - square_radius;
    // No tangent from a site inside the circle: straight, held or not.
    if switching[1] < 0.0 || radius < MIN_VALUE {
        return (WrapPath::Straight, None);
    }
    let difference = [ends[2] - ends[0], ends[3] - ends[1]];
    let dd = difference[0] * difference[0] + difference[1] * difference[1];
    if dd.value() < MIN_VALUE {
        return (WrapPath::Straight, None);
    }
    // The segment's point nearest the centre.
    let a = (-(difference[0] * ends[0] + difference[1] * ends[1]) / dd).clamp(S::zero(), S::one());
    let nearest = [a * difference[0] + ends[0], a * difference[1] + ends[1]];
    switching[0] = square_radius - (nearest[0] * nearest[0] + nearest[1] * nearest[1]).value();
    if switching[0] < 0.0 && held.is_none_or(|path| path == WrapPath::Straight) {
        return (WrapPath::Straight, None);
    }
    let root0 = (square0 - square_radius).sqrt();
    let root1 = (square1 - square_radius).sqrt();
    // The two pairs of tangent points, and how good each is: the shorter
    // chord; crossing tangents are worst.
    let mut solutions = [[S::zero(); 4]; 2];
    let mut goodness = [0.0; 2];
    for (i, sign) in [1.0, -1.0].into_iter().enumerate() {
        let s = &mut solutions[i];
        let arm = sign * radius;
        s[0] = (ends[0] * square_radius + ends[1] * arm * root0) / square0;
        s[1] = (ends[1] * square_radius - ends[0] * arm * root0) / square0;
        s[2] = (ends[2] * square_radius - ends[3] * arm * root1) / square1;
        s[3] = (ends[3] * square_radius + ends[2] * arm * root1) / square1;
        let chord = [(s[0] - s[2]).value(), (s[1] - s[3]).value()];
        goodness[i] = -(chord[0] * chord[0] + chord[1] * chord[1]);
        if segments_cross(&ends[0..2], &s[0..2], &ends[2..4], &s[2..4]) {
            goodness[i] = -10000.0;
        }
    }
    let i = if goodness[0] > goodness[1] { 0 } else { 1 };
    switching[2] = goodness[0] - goodness[1];
    let chosen = solutions[i];
    let natural = if switching[0] < 0.0 || segments_cross(&ends[0..2], &chosen[0..2], &ends[2..4], &chosen[2..4]) {
        WrapPath::Straight
    } else {
        WrapPath::Around(i)
    };
    match held.unwrap_or(natural) {
        WrapPath::Straight => (WrapPath::Straight, None),
        path @ WrapPath::Around(i) => {
            let s = solutions[i];
            let length = arc_length(&[s[0], s[1]], &[s[2], s[3]], i == 1, radius, natural == WrapPath::Straight);
            (path, Some((length, s)))
        }
    }
}

/// The wrap of the 2D segment `ends` (x₀, y₀, x₁, y₁) around the circle of
/// `radius` that goes round the centre as the polyline from its start
/// through `side` to its end does: the arc's length and its end points
/// (x, y, x, y), or `None` when the straight segment is that path. The
/// polyline turns w about the centre, each tangent segment acos(r/|p|), so
/// the arc turns |w| − acos(r/|p₀|) − acos(r/|p₁|) in the sense of w, and
/// the straight segment is the path when that is not positive.
///
/// w is the sum of the two turns p₀ → side → p₁, each in [−π, π): where
/// one passes ±π the polyline passes the centre and the path jumps to the
/// other way round. A `held` wrap ([`WrapPath::Around`] with the turns'
/// and w's signs as bits 0, 1 and 2) goes on from where it was decided: a
/// turn that has passed ±π taken on past it, w's sense kept, and an arc
/// through zero going on negative. `switching` as [`wrap`]'s, the last
/// being π minus the larger turn so taken on.
fn wrap_circle_through<S: Real>(
    ends: &[S; 4],
    side: Point<S>,
    radius: f64,
    held: Option<WrapPath>,
    switching: &mut [f64; WRAP_SWITCHES],
) -> (WrapPath, Option<(S, [S; 4])>) {
    let (norm0, norm1) = (ends[0].hypot(ends[1]), ends[2].hypot(ends[3]));
    switching[1] = norm0.value().min(norm1.value()) - radius;
    if norm0.value() < radius || norm1.value() < radius || radius < MIN_VALUE {
        return (WrapPath::Straight, None);
    }
    let (angle0, angle1, angle_side) = (
        ends[1].atan2_differentiable(ends[0]),
        ends[3].atan2_differentiable(ends[2]),
        side[1].atan2_differentiable(side[0]),
    );
    let mut turns = [turn(angle_side - angle0), turn(angle1 - angle_side)];
    let (tangent0, tangent1) = ((S::from(radius) / norm0).acos(), (S::from(radius) / norm1).acos());
    let mut winding = turns[0] + turns[1];
    let arc = |winding: S, positive: bool| if positive { winding } else { -winding } - tangent0 - tangent1;
    let mut positive = winding.value() >= 0.0;
    switching[0] = arc(winding, positive).value();
    let natural = if switching[0] <= 0.0 {
        WrapPath::Straight
    } else {
        let bit = |b: bool, k: usize| usize::from(b) << k;
        WrapPath::Around(bit(turns[0].value() >= 0.0, 0) | bit(turns[1].value() >= 0.0, 1) | bit(positive, 2))
    };
    match held {
        None => {}
        Some(WrapPath::Straight) => return (WrapPath::Straight, None),
        Some(WrapPath::Around(bits)) => {
            for (k, turn) in turns.iter_mut().enumerate() {
                // Past ±π the turn's sign flips at a large size; through 0 at a small one.
                let was_positive = bits & (1 << k) != 0;
                if (turn.value() >= 0.0) != was_positive && turn.value().abs() > FRAC_PI_2 {
                    *turn += if was_positive { 2.0 * PI } else { -2.0 * PI };
                }
            }
            winding = turns[0] + turns[1];
            positive = bits & 4 != 0;
        }
    }
    // Where a turn taken on from the decision passes ±π.
    switching[2] = PI - turns[0].value().abs().max(turns[1].value().abs());
    let path = held.unwrap_or(natural);
    if path == WrapPath::Straight {
        return (path, None);
    }
    let sense = if positive { 1.0 } else { -1.0 };
    let (at0, at1) = (angle0 + tangent0 * sense, angle1 - tangent1 * sense);
    let points = [at0.cos() * radius, at0.sin() * radius, at1.cos() * radius, at1.sin() * radius];
    (path, Some((arc(winding, positive) * radius, points)))
}

/// An angle brought into [−π, π): (angle + π) mod 2π − π, the whole turns
/// taken off by their count (exact in f64, as `rem_euclid` is, for the
/// differences of two `atan2` this takes).
fn turn<S: Real>(angle: S) -> S {
    let shifted = angle + PI;
    let turns = (shifted.value() / (2.0 * PI)).floor();
    shifted - turns * (2.0 * PI) - PI
}
