//! The attribute tables of the elements that make the body tree: `<body>`,
//! `<frame>`, `<replicate>`, `<inertial>` and `<freejoint>`, and the
//! settings each reads (as written: the reader resolves orientations,
//! composes frames and computes mass properties from them).

use super::attributes::{Attribute, set};
use super::element::Element;
use super::error::MjcfError;
use super::orientation::Orientation;

/// What a `<body>` element gives besides its name, class and children.
#[derive(Clone, Debug, Default)]
pub(crate) struct BodySettings {
    /// `pos`, in the parent (or the `<frame>` around it).
    pub pos: [f64; 3],
    /// `quat` or one of its alternatives.
    pub orientation: Orientation,
    /// `mocap`.
    pub mocap: bool,
    /// `gravcomp`.
    pub gravcomp: f64,
    /// Whether `sleep` gives a policy other than "auto" (only movable root
    /// bodies may have one).
    pub sleep_policy: bool,
}

/// `<body>` (MuJoCo 4.0 schema): its attributes and how each is read.
pub(crate) const BODY_ATTRIBUTES: &[Attribute<BodySettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("childclass"),
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?)),
    // An orientation written on the element is read once whichever attribute gives it.
    Attribute::into("quat", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("axisangle", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("xyaxes", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("zaxis", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("euler", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("mocap", |s, e, a| set(&mut s.mocap, e.boolean(a)?)),
    Attribute::into("gravcomp", |s, e, a| set(&mut s.gravcomp, e.number(a)?)),
    Attribute::no_effect("user"),
    // MuJoCo 4.0's keywords; its rule for a policy other than "auto" is the reader's.
    Attribute::into("sleep", |s, e, a| {
        let policies = [("auto", false), ("never", true), ("allowed", true), ("init", true)];
        set(&mut s.sleep_policy, e.keyword(a, &policies)?)
    }),
    Attribute::no_effect("simple"),
    Attribute::checked("fuse", |e, a| e.keyword(a, &[("auto", ()), ("false", ())]).map(drop)),
];

/// What a `<frame>` element gives: the pose of what it holds.
#[derive(Clone, Debug, Default)]
pub(crate) struct FrameSettings {
    /// `pos`.
    pub pos: [f64; 3],
    /// `quat` or one of its alternatives.
    pub orientation: Orientation,
}

/// `<frame>` (MuJoCo 4.0 schema). Its name names nothing nudyn keeps: a
/// frame vanishes into what it places.
pub(crate) const FRAME_ATTRIBUTES: &[Attribute<FrameSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("childclass"),
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?)),
    // An orientation written on the element is read once whichever attribute gives it.
    Attribute::into("quat", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("axisangle", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("xyaxes", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("zaxis", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("euler", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
];

/// What a `<replicate>` element gives.
#[derive(Clone, Debug, Default)]
pub(crate) struct ReplicateSettings {
    /// `count`: the number of copies, positive (required).
    pub count: Option<i32>,
    /// `sep`: what comes between a name and its copy's number.
    pub separator: String,
    /// `offset`: each copy's position in the last one's frame.
    pub offset: [f64; 3],
    /// `euler`: each copy's turn from the last one, in the compiler's angle unit and sequence.
    pub euler: [f64; 3],
}

/// `<replicate>` (MuJoCo 4.0 schema).
pub(crate) const REPLICATE_ATTRIBUTES: &[Attribute<ReplicateSettings>] = &[
    Attribute::into("count", |s, e, a| match e.integers::<1>(a)? {
        Some([count]) if count <= 0 => Err(e.bad_value(a, "a positive number of copies")),
        count => set(&mut s.count, count.map(|[count]| Some(count))),
    }),
    Attribute::into("sep", |s, e, a| set(&mut s.separator, e.text(a).map(str::to_string))),
    Attribute::into("offset", |s, e, a| set(&mut s.offset, e.numbers(a)?)),
    Attribute::into("euler", |s, e, a| set(&mut s.euler, e.numbers(a)?)),
    Attribute::by_reader("childclass"),
];

/// What an `<inertial>` element gives, as written.
#[derive(Clone, Debug, Default)]
pub(crate) struct InertialSettings {
    /// `pos`: the centre of mass (required).
    pub pos: Option<[f64; 3]>,
    /// `mass` (required).
    pub mass: Option<f64>,
    /// `diaginertia`: the principal moments.
    pub diaginertia: [f64; 3],
    /// `fullinertia`: xx, yy, zz, xy, xz, yz (without an orientation or `diaginertia`).
    pub fullinertia: Option<[f64; 6]>,
    /// The principal axes: `quat` or one of its alternatives.
    pub orientation: Option<Orientation>,
}

/// `<inertial>` (MuJoCo 4.0 schema).
pub(crate) const INERTIAL_ATTRIBUTES: &[Attribute<InertialSettings>] = &[
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?.map(Some))),
    Attribute::into("mass", |s, e, a| set(&mut s.mass, e.non_negative(a)?.map(Some))),
    Attribute::into("diaginertia", |s, e, a| set(&mut s.diaginertia, e.non_negative_numbers(a)?)),
    Attribute::into("fullinertia", |s, e, a| set(&mut s.fullinertia, e.numbers(a)?.map(Some))),
    Attribute::into("quat", |s, e, _| set(&mut s.orientation, Orientation::read(e)?.map(Some))),
    Attribute::into("axisangle", |s, e, _| set(&mut s.orientation, Orientation::read(e)?.map(Some))),
    Attribute::into("xyaxes", |s, e, _| set(&mut s.orientation, Orientation::read(e)?.map(Some))),
    Attribute::into("zaxis", |s, e, _| set(&mut s.orientation, Orientation::read(e)?.map(Some))),
    Attribute::into("euler", |s, e, _| set(&mut s.orientation, Orientation::read(e)?.map(Some))),
];

/// `align` of a free joint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Align {
    /// "false": the body frame stays where the file puts it.
    No,
    /// "true": the body frame moves to the inertial frame.
    Yes,
    /// "auto": as `<compiler alignfree>` says.
    #[default]
    Auto,
}

/// What a `<freejoint>` element gives. It takes no defaults (MuJoCo's rule).
#[derive(Clone, Debug, Default)]
pub(crate) struct FreeJointSettings {
    /// `align`.
    pub align: Align,
}

/// `<freejoint>` (MuJoCo 4.0 schema).
pub(crate) const FREEJOINT_ATTRIBUTES: &[Attribute<FreeJointSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::no_effect("group"),
    Attribute::into("align", |s, e, a| {
        set(&mut s.align, e.keyword(a, &[("false", Align::No), ("true", Align::Yes), ("auto", Align::Auto)])?)
    }),
];

/// Reads the attributes `table` gives into settings that start from `S`'s
/// default, after checking that the element has no other attribute.
pub(crate) fn read_settings<S: Default>(table: &[Attribute<S>], element: &Element) -> Result<S, MjcfError> {
    element.check_attributes(&super::attributes::names(table))?;
    let mut settings = S::default();
    super::attributes::read_into(table, &mut settings, element)?;
    Ok(settings)
}
