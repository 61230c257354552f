//! Compiled tendons: each path resolved into θ and dof addresses (fixed
//! tendons) or site frames on links (spatial tendons), with the lengths
//! MuJoCo computes in qpos0 and in the spring pose (docs/DYNAMICS.md §9).
//! Their lengths, moment arms and velocities at a state are
//! [`crate::dynamics::tendon`]'s.

use serde::{Deserialize, Serialize};

use super::{Attachment, JointInfo, LinkJoint, Model, SiteFrame};
use crate::math::Transform;
use crate::vehicle::{PathPoint, TendonPath, Vehicle};

/// One compiled tendon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tendon {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// What its length is measured along.
    pub path: Path,
    /// `stiffness`.
    pub stiffness: f64,
    /// `damping`.
    pub damping: f64,
    /// `armature`: MuJoCo adds armature·JᵀJ to the mass matrix, within its
    /// tree sparsity ([`InertiaTerm`]).
    pub armature: f64,
    /// `actuatorfrcrange` when limited: the forces of the tendon's actuators
    /// are scaled alike to bring their sum into it, before each one's
    /// `forcerange` (MuJoCo's `mj_fwdActuation`).
    pub actuator_force_range: Option<[f64; 2]>,
    /// The lengths between which the spring is at rest (MuJoCo's
    /// `tendon_lengthspring`, its −1 resolved in the spring pose).
    pub spring_length: [f64; 2],
    /// The length in qpos0 (MuJoCo's `tendon_length0`), from which a tendon
    /// equality measures.
    pub length0: f64,
    /// J M⁻¹ Jᵀ in qpos0 (MuJoCo's `tendon_invweight0`), the scale of its
    /// constraint rows' regularizer.
    pub invweight0: f64,
    /// Line of the element in the MJCF file (1-based).
    pub line: u32,
}

impl Tendon {
    /// The tendon as messages name it: its element and name, or its index.
    pub fn label(&self, index: usize) -> String {
        let element = match self.path {
            Path::Fixed { .. } => "fixed",
            Path::Spatial { .. } => "spatial",
        };
        match &self.name {
            Some(name) => format!("<{element}> tendon '{name}'"),
            None => format!("<{element}> tendon {index}"),
        }
    }

    /// Whether its spring or damper can push (MuJoCo skips it otherwise).
    pub fn has_passive_force(&self) -> bool {
        self.stiffness != 0.0 || self.damping != 0.0
    }
}

/// A tendon's path, compiled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum Path {
    /// Σ coef · θ over hinge and slide joints: constant moment arms.
    Fixed {
        /// The joints and their coefficients.
        terms: Vec<FixedTerm>,
    },
    /// Straight segments between consecutive sites.
    Spatial {
        /// The sites and pulleys, in order.
        stops: Vec<PathStop>,
    },
}

/// One joint of a fixed tendon.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FixedTerm {
    /// The joint's θ entry.
    pub qpos: usize,
    /// The joint's dof.
    pub dof: usize,
    /// `coef`.
    pub coef: f64,
}

/// How many switching functions a wrap has: whether the segment meets its
/// geom, whether both sites are outside it, which way round it goes
/// (`Workspace::wrap_switching`).
pub const WRAP_SWITCHES: usize = 3;

/// One element of a spatial tendon's path.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum PathStop {
    /// A site on its link (or the world).
    Site {
        /// The site's frame.
        frame: SiteFrame,
        /// The MJCF body carrying it (`None`: the world): MuJoCo gives a
        /// segment between two sites of one body no moment arms.
        body: Option<usize>,
    },
    /// A sphere or cylinder the segment between the sites around it wraps around.
    Geom {
        /// The geom's frame on its link (a cylinder's axis is its z).
        frame: SiteFrame,
        /// The MJCF body carrying it.
        body: Option<usize>,
        /// Its radius.
        radius: f64,
        /// A cylinder (else a sphere).
        cylinder: bool,
        /// Its side site: the tendon goes round the geom as the polyline
        /// from the first site through it to the second does.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        side: Option<SiteFrame>,
    },
    /// A pulley: the segments after it count 1/divisor.
    Pulley {
        /// `divisor`.
        divisor: f64,
    },
}

/// The tendons of `vehicle`, their joints resolved against the compiled
/// `joints` and their sites at `sites`; their lengths and invweights at
/// qpos0 come from the qpos0 stage ([`super::Qpos0Constants`]). The
/// importer has checked every name.
pub(super) fn compile_tendons(
    vehicle: &Vehicle,
    joints: &[JointInfo],
    sites: &[SiteFrame],
    attachments: &[Attachment],
) -> Vec<Tendon> {
    vehicle
        .tendons
        .iter()
        .map(|tendon| {
            let path = match &tendon.path {
                TendonPath::Fixed(terms) => Path::Fixed {
                    terms: terms
                        .iter()
                        .map(|(name, coef)| {
                            let joint = joints.iter().find(|j| &j.name == name).expect("the importer checked it");
                            FixedTerm { qpos: joint.qpos_adr, dof: joint.dof_adr, coef: *coef }
                        })
                        .collect(),
                },
                TendonPath::Spatial(points) => Path::Spatial {
                    stops: points
                        .iter()
                        .map(|point| match *point {
                            PathPoint::Site(site) => {
                                PathStop::Site { frame: sites[site], body: vehicle.sites[site].body }
                            }
                            PathPoint::Pulley(divisor) => PathStop::Pulley { divisor },
                            PathPoint::Geom(geom) => {
                                let in_body =
                                    Transform::from_pose(&geom.quat.to_rotation_matrix().into_inner(), &geom.pos);
                                let frame = match geom.body {
                                    Some(b) => SiteFrame {
                                        link: attachments[b].link,
                                        frame: in_body.compose(&attachments[b].offset),
                                        node: None,
                                    },
                                    None => SiteFrame { link: None, frame: in_body, node: None },
                                };
                                PathStop::Geom {
                                    frame,
                                    body: geom.body,
                                    radius: geom.radius,
                                    cylinder: geom.cylinder,
                                    side: geom.side.map(|site| sites[site]),
                                }
                            }
                        })
                        .collect(),
                },
            };
            Tendon {
                name: tendon.name.clone(),
                path,
                stiffness: tendon.stiffness,
                damping: tendon.damping,
                armature: tendon.armature,
                actuator_force_range: tendon.actuator_force_range,
                // Resolved in the spring pose when the file leaves it to MuJoCo (−1).
                spring_length: tendon.spring_length.unwrap_or_default(),
                length0: 0.0,
                invweight0: 0.0,
                line: tendon.line,
            }
        })
        .collect()
}

/// Checks tendon `k` against the links: a fixed tendon's terms on hinge or
/// slide joints, a spatial tendon's sites on existing links with proper
/// placements, positive divisors, finite numbers.
pub(super) fn validate_tendon(model: &Model, k: usize) -> Result<(), String> {
    let tendon = &model.tendons[k];
    let scalar_joint = |term: &FixedTerm| {
        let link = model.links.iter().find(|l| l.dof_adr == term.dof);
        link.is_some_and(|l| matches!(l.joint, LinkJoint::Hinge | LinkJoint::Slide) && l.qpos_adr == term.qpos)
    };
    let fits = match &tendon.path {
        Path::Fixed { terms } => !terms.is_empty() && terms.iter().all(|t| scalar_joint(t) && t.coef.is_finite()),
        Path::Spatial { stops } => {
            stops.len() >= 2
                && stops.iter().all(|stop| match stop {
                    PathStop::Site { frame, .. } => {
                        frame.link.is_none_or(|l| l < model.links.len())
                            && super::validate::placement_is_proper(&frame.frame)
                    }
                    PathStop::Pulley { divisor } => divisor.is_finite() && *divisor > 0.0,
                    PathStop::Geom { frame, radius, side, .. } => {
                        side.iter().all(|s| s.link == frame.link && super::validate::placement_is_proper(&s.frame))
                            && frame.link.is_none_or(|l| l < model.links.len())
                            && super::validate::placement_is_proper(&frame.frame)
                            && radius.is_finite()
                            && *radius > 0.0
                    }
                })
        }
    };
    if !fits {
        return Err("its path does not match the links".to_string());
    }
    if let Path::Spatial { stops } = &tendon.path {
        let site = |k: Option<usize>| k.and_then(|k| stops.get(k)).is_some_and(|s| matches!(s, PathStop::Site { .. }));
        let bracketed = (0..stops.len())
            .filter(|&k| matches!(stops[k], PathStop::Geom { .. }))
            .all(|k| site(k.checked_sub(1)) && site(Some(k + 1)));
        if !bracketed {
            return Err("a geom of its path is not between two sites".to_string());
        }
    }
    let numbers = [tendon.stiffness, tendon.damping, tendon.armature, tendon.length0, tendon.invweight0];
    if !numbers.iter().chain(&tendon.spring_length).all(|x| x.is_finite()) {
        return Err("stiffness, damping, armature, spring length and qpos0 data must be finite".to_string());
    }
    if tendon.armature < 0.0 {
        return Err("its armature is negative".to_string());
    }
    if tendon.actuator_force_range.is_some_and(|[low, high]| !(low <= 0.0 && 0.0 <= high && low < high)) {
        return Err("its actuator force range must hold 0 and be increasing".to_string());
    }
    if tendon.armature > 0.0
        && let Path::Spatial { stops } = &tendon.path
        && stops.iter().any(|s| matches!(s, PathStop::Geom { .. }))
    {
        return Err("it has armature and wraps a geom, which MuJoCo refuses".to_string());
    }
    Ok(())
}

/// One term of the tendons' armature as MuJoCo adds it to the mass matrix.
///
/// MuJoCo adds a·J_iJ_j only where M has room in its tree sparsity: for
/// dofs i, j one of which is the other's ancestor (or i = j); the coupling
/// of two dofs on different branches is dropped. Over the tree that the
/// tendon's dofs S form (each dof's parent its nearest ancestor in S), that
/// masked a·JᵀJ is Σ_v a·(1 − children(v))·U_vᵀU_v, U_v the moment arms kept
/// on v and its ancestors only: a pair (i, j), j below i, lies in the U_v of
/// every v below j, and the weights of a subtree sum to its nodes less its
/// edges, 1. Only the leaves (+a) and the forks (−a per child beyond the
/// first) are terms, so a tendon whose dofs lie on one chain is the one term
/// a·JᵀJ. The same weights sum the U_v to J, so the bias a·J(J̇θ̇) is
/// Σ_v a·(1 − children(v))·U_v(J̇θ̇) too.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct InertiaTerm {
    /// The tendon.
    pub tendon: usize,
    /// The dof v whose ancestors (and itself) keep the tendon's moment arms.
    pub dof: usize,
    /// Its link.
    pub link: usize,
    /// a·(1 − children(v)).
    pub weight: f64,
}

/// The armature terms of the model's tendons, in tendon order (none when no
/// tendon has armature).
pub(super) fn inertia_terms(model: &Model) -> Vec<InertiaTerm> {
    let mut terms = Vec::new();
    // Each dof's link, and its parent in MuJoCo's dof tree: the dof before
    // it in a multi-dof joint, else the last dof of the parent link.
    let mut dof_link = vec![0; model.nv];
    let mut dof_parent = vec![None; model.nv];
    for (l, link) in model.links.iter().enumerate() {
        for c in 0..link.ndof {
            let dof = link.dof_adr + c;
            dof_link[dof] = l;
            dof_parent[dof] = match (c, link.parent) {
                (0, Some(p)) => Some(model.links[p].dof_adr + model.links[p].ndof - 1),
                (0, None) => None,
                _ => Some(dof - 1),
            };
        }
    }
    for (k, tendon) in model.tendons.iter().enumerate() {
        if tendon.armature == 0.0 {
            continue;
        }
        let mut in_support = vec![false; model.nv];
        match &tendon.path {
            Path::Fixed { terms } => terms.iter().for_each(|t| in_support[t.dof] = true),
            Path::Spatial { stops } => {
                for stop in stops {
                    if let PathStop::Site { frame: SiteFrame { link: Some(l), .. }, .. } = stop {
                        let link = &model.links[*l];
                        let mut dof = (link.ndof > 0).then(|| link.dof_adr + link.ndof - 1);
                        while let Some(d) = dof {
                            in_support[d] = true;
                            dof = dof_parent[d];
                        }
                    }
                }
            }
        }
        let mut children = vec![0usize; model.nv];
        for d in 0..model.nv {
            if in_support[d] {
                let mut up = dof_parent[d];
                while let Some(u) = up.filter(|&u| !in_support[u]) {
                    up = dof_parent[u];
                }
                if let Some(u) = up {
                    children[u] += 1;
                }
            }
        }
        for d in (0..model.nv).filter(|&d| in_support[d] && children[d] != 1) {
            let weight = tendon.armature * (1.0 - children[d] as f64);
            terms.push(InertiaTerm { tendon: k, dof: d, link: dof_link[d], weight });
        }
    }
    terms
}
