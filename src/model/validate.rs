//! [`Model::validate`]: the shape every pass relies on. A model that passes
//! has parent-first links with consecutive coordinates and dofs, vectors of
//! the declared sizes, finite numbers, and no shortcut past a term it has.
//!
//! [`Model::compile`] checks what it builds with it (a number that
//! overflowed while compiling is caught here), and the FMU checks the model
//! it reads from its resources, which may be corrupted or hand-edited: such
//! a file must be refused at instantiation with a message, not crash, hang
//! or allocate without bound later.

use super::{LinkJoint, Model};

/// What is wrong with a compiled model.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InvalidModel {
    /// No links at all.
    #[error("the model has no links")]
    NoLinks,
    /// A parent that does not come before its child.
    #[error("link {link} has parent {parent}: parents must come first")]
    Parent {
        /// The link.
        link: usize,
        /// Its parent.
        parent: usize,
    },
    /// A dof count that does not fit the joint.
    #[error("link {link} is a {joint:?} joint with {ndof} dofs, expected {expected}")]
    Dofs {
        /// The link.
        link: usize,
        /// Its joint.
        joint: LinkJoint,
        /// Its dof count.
        ndof: usize,
        /// The joint's dof count.
        expected: usize,
    },
    /// Coordinates or dofs that are not consecutive in link order.
    #[error("link {link} starts at {what} {found}, expected {expected}")]
    Address {
        /// The link.
        link: usize,
        /// "qpos" or "dof".
        what: &'static str,
        /// Its address.
        found: usize,
        /// The end of the previous link's.
        expected: usize,
    },
    /// A size that does not match the links.
    #[error("{what} is {found}, the links give {expected}")]
    Size {
        /// Which size.
        what: &'static str,
        /// The value in the file.
        found: usize,
        /// The value the links imply.
        expected: usize,
    },
    /// A joint whose coordinates or dofs lie outside the vectors.
    #[error("joint '{joint}' lies outside the coordinates or dofs")]
    JointAddress {
        /// The joint name.
        joint: String,
    },
    /// A number that is not finite, or negative where it must not be.
    #[error("{what} of link {link} is {value}: must be finite{}", if *.non_negative { " and non-negative" } else { "" })]
    Number {
        /// The link (or 0 for model-wide values).
        link: usize,
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// Whether the quantity must also be non-negative.
        non_negative: bool,
    },
    /// A shortcut that would skip a term the model has.
    #[error("the model takes the shortcut {0}, but it has that term")]
    Shortcut(&'static str),
}

/// (qpos count, dof count) of a link's joint.
fn joint_size(joint: LinkJoint) -> (usize, usize) {
    match joint {
        LinkJoint::Hinge | LinkJoint::Slide => (1, 1),
        LinkJoint::Ball => (4, 3),
        LinkJoint::Translation => (3, 3),
    }
}

/// The first non-finite value of `values`, as an error about `what` of `link`.
fn finite<'a>(link: usize, what: &'static str, values: impl IntoIterator<Item = &'a f64>) -> Result<(), InvalidModel> {
    match values.into_iter().find(|x| !x.is_finite()) {
        Some(&value) => Err(InvalidModel::Number { link, what, value, non_negative: false }),
        None => Ok(()),
    }
}

/// A value that must be finite and non-negative.
fn non_negative(link: usize, what: &'static str, value: f64) -> Result<(), InvalidModel> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(InvalidModel::Number { link, what, value, non_negative: true })
    }
}

impl Model {
    /// Checks that the model has the structure [`Model::compile`] gives; O(links).
    pub fn validate(&self) -> Result<(), InvalidModel> {
        validate(self)
    }
}

fn validate(model: &Model) -> Result<(), InvalidModel> {
    if model.links.is_empty() {
        return Err(InvalidModel::NoLinks);
    }
    let (mut nq, mut nv) = (0, 0);
    for (k, link) in model.links.iter().enumerate() {
        if let Some(parent) = link.parent.filter(|&p| p >= k) {
            return Err(InvalidModel::Parent { link: k, parent });
        }
        let (link_nq, link_nv) = joint_size(link.joint);
        if link.ndof != link_nv {
            return Err(InvalidModel::Dofs { link: k, joint: link.joint, ndof: link.ndof, expected: link_nv });
        }
        if link.qpos_adr != nq {
            return Err(InvalidModel::Address { link: k, what: "qpos", found: link.qpos_adr, expected: nq });
        }
        if link.dof_adr != nv {
            return Err(InvalidModel::Address { link: k, what: "dof", found: link.dof_adr, expected: nv });
        }
        nq += link_nq;
        nv += link_nv;
        finite(k, "x_tree", link.x_tree.rot.iter().chain(link.x_tree.trans.iter()))?;
        finite(k, "axis", link.axis.iter())?;
        finite(k, "anchor", link.anchor.iter())?;
        finite(k, "reference", [link.reference].iter())?;
        finite(k, "motion_subspace", link.motion_subspace.iter())?;
        finite(k, "rotational_inertia", link.rotational_inertia.iter())?;
        finite(k, "mass_moment", link.mass_moment.iter())?;
        non_negative(k, "armature", link.armature)?;
        non_negative(k, "stiffness", link.stiffness)?;
        non_negative(k, "damping", link.damping)?;
        non_negative(k, "mass", link.mass)?;
    }
    for (what, found, expected) in [
        ("nq", model.nq, nq),
        ("nv", model.nv, nv),
        ("the length of qpos0", model.qpos0.len(), nq),
        ("the length of qpos_spring", model.qpos_spring.len(), nq),
    ] {
        if found != expected {
            return Err(InvalidModel::Size { what, found, expected });
        }
    }
    if let Some(joint) = model.joints.iter().find(|j| j.qpos_adr >= nq || j.dof_adr >= nv) {
        return Err(InvalidModel::JointAddress { joint: joint.name.clone() });
    }
    finite(0, "gravity", model.gravity.iter())?;
    finite(0, "qpos0", &model.qpos0)?;
    finite(0, "qpos_spring", &model.qpos_spring)?;
    match model.shortcuts.not_allowed_for(model) {
        Some(shortcut) => Err(InvalidModel::Shortcut(shortcut)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn example(name: &str) -> Model {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples").join(name);
        let vehicle = crate::mjcf::load_mjcf(&path).expect("example imports").vehicle;
        Model::compile(&vehicle).expect("example compiles")
    }

    #[test]
    fn compiled_examples_pass() {
        for name in ["bus_arm7.xml", "flexible_boom.xml", "fixed_rig.xml", "chain60.xml"] {
            assert_eq!(validate(&example(name)), Ok(()), "{name}");
        }
    }

    #[test]
    fn sizes_that_do_not_match_the_links_are_refused() {
        let mut model = example("bus_arm7.xml");
        // A flipped digit in "nv" would otherwise size every vector (and the GUID's variable list) by it.
        model.nv = 1_000_000_000_000;
        assert!(matches!(validate(&model), Err(InvalidModel::Size { what: "nv", .. })));
        let mut model = example("bus_arm7.xml");
        model.qpos0.pop();
        assert!(matches!(validate(&model), Err(InvalidModel::Size { .. })));
    }

    #[test]
    fn broken_structure_is_refused() {
        let mut model = example("bus_arm7.xml");
        model.links[3].parent = Some(5);
        assert_eq!(validate(&model), Err(InvalidModel::Parent { link: 3, parent: 5 }));
        let mut model = example("bus_arm7.xml");
        model.links[2].ndof = 3;
        assert!(matches!(validate(&model), Err(InvalidModel::Dofs { link: 2, .. })));
        let mut model = example("bus_arm7.xml");
        model.links[4].qpos_adr += 1;
        assert!(matches!(validate(&model), Err(InvalidModel::Address { link: 4, what: "qpos", .. })));
        let mut model = example("bus_arm7.xml");
        model.links.clear();
        assert_eq!(validate(&model), Err(InvalidModel::NoLinks));
        let mut model = example("bus_arm7.xml");
        model.joints[1].dof_adr = model.nv;
        assert!(matches!(validate(&model), Err(InvalidModel::JointAddress { .. })));
    }

    #[test]
    fn bad_numbers_are_refused() {
        let mut model = example("flexible_boom.xml");
        model.links[1].rotational_inertia[(2, 2)] = f64::NAN;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { link: 1, what: "rotational_inertia", .. })));
        let mut model = example("flexible_boom.xml");
        model.links[0].mass = -1.0;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { what: "mass", non_negative: true, .. })));
        let mut model = example("flexible_boom.xml");
        model.gravity[2] = f64::INFINITY;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { what: "gravity", .. })));
    }

    #[test]
    fn a_shortcut_past_a_term_the_model_has_is_refused() {
        // bus_arm7 has no gravity but has armature: an edited file must not skip it.
        let mut model = example("bus_arm7.xml");
        assert!(model.shortcuts.no_gravity && !model.shortcuts.no_armature);
        model.shortcuts.no_armature = true;
        assert_eq!(validate(&model), Err(InvalidModel::Shortcut("no_armature")));
        model.shortcuts = crate::model::Shortcuts::none();
        assert_eq!(validate(&model), Ok(()));
    }
}
