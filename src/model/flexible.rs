//! Flexible bodies on the links that carry them (docs/flexible.md): each
//! body's nodes and mode shapes brought into its link's frame, so that the
//! passes place the modal block at the link frame whatever joints (or none)
//! put the body there, and its modal coordinates' places in θ and ν, after
//! every rigid coordinate.

use serde::{Deserialize, Serialize};

use crate::flex::point_masses::{PointMasses, is_point_mass};
use crate::flex::{ModalBody, Mode, Node};
use crate::math::{SpatialMat, Transform, Vec3, rigid_inertia};

/// One flexible body with modes, as the passes see it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlexBody {
    /// The link whose frame carries the body's frame (the modal block's
    /// reference frame R is this link's frame).
    pub link: usize,
    /// First θ entry of its modal coordinates η.
    pub qpos_adr: usize,
    /// First ν (and θ̇) entry of its modal rates.
    pub dof_adr: usize,
    /// Its nodes and modes in the link's frame and axes (the node frames'
    /// axes are the link's when undeformed); the body's name is kept.
    pub modal: ModalBody,
    /// The nodes the passes take one by one (with rotary inertia or a
    /// rotation in some mode), by index into `modal.nodes`.
    pub rotating: Vec<usize>,
    /// The other nodes, point masses, summed in closed form.
    pub points: PointMasses,
    /// The child bodies at nodes (docs/flexible.md, "Child bodies at
    /// nodes"): their first links, whose parent frame is the node's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub node_children: Vec<NodeChild>,
    /// Per entry of `rotating`: whether some child body rides that node.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub carries: Vec<bool>,
    /// Per entry of `rotating` (empty when no body is welded at a node):
    /// the spatial inertia of the bodies welded at that node, about its
    /// origin in its axes (docs/flexible.md, "Bodies welded at nodes").
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub welded: Vec<SpatialMat>,
}

/// A child body at a node: its first link, whose `x_tree` is relative to
/// the node's frame, and the node it rides.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeChild {
    /// The child's first link (its parent is the flexible body's link).
    pub link: usize,
    /// The node, by index into `FlexBody::rotating` (a node carrying a
    /// child is always taken one by one).
    pub slot: usize,
}

impl FlexBody {
    /// The body `modal` (in its link's frame) on `link`, its coordinates at
    /// `qpos_adr` and `dof_adr`, carrying child bodies whose first links
    /// ride nodes as `children` gives them (link, node index into `modal.nodes`),
    /// and bodies welded at nodes as `welded` gives their inertias (node
    /// index, spatial inertia about the node in its axes).
    pub(crate) fn new(
        link: usize,
        qpos_adr: usize,
        dof_adr: usize,
        modal: ModalBody,
        children: &[(usize, usize)],
        welded: &[(usize, SpatialMat)],
    ) -> FlexBody {
        // A node carrying a child, or a welded body, is a full rigid node: the
        // child's articulated inertia, or the welded body's inertia with its
        // first moment about the node, joins the node's, which the
        // point-mass sums cannot hold.
        let carried = |j: usize| children.iter().any(|&(_, node)| node == j);
        let weld = |j: usize| welded.iter().any(|&(node, _)| node == j);
        let rotating: Vec<usize> =
            (0..modal.nodes.len()).filter(|&j| !is_point_mass(&modal, j) || carried(j) || weld(j)).collect();
        let points = PointMasses::of(&modal, &rotating);
        let slot = |j: usize| rotating.iter().position(|&r| r == j).expect("a carrying node is taken one by one");
        let node_children = children.iter().map(|&(link, node)| NodeChild { link, slot: slot(node) }).collect();
        let carries = if children.is_empty() { Vec::new() } else { rotating.iter().map(|&j| carried(j)).collect() };
        let welded = match welded.is_empty() {
            true => Vec::new(),
            false => rotating
                .iter()
                .map(|&j| welded.iter().filter(|&&(node, _)| node == j).map(|(_, inertia)| inertia).sum())
                .collect(),
        };
        FlexBody { link, qpos_adr, dof_adr, modal, rotating, points, node_children, carries, welded }
    }

    /// The spatial inertia of the node in slot `r` of `rotating`, about its
    /// origin in its axes: its mass and rotary inertia, and the bodies
    /// welded at it.
    pub fn node_inertia(&self, r: usize) -> SpatialMat {
        let node = &self.modal.nodes[self.rotating[r]];
        let own = rigid_inertia(node.mass, &Vec3::zeros(), &node.rotary_inertia);
        match self.welded.get(r) {
            Some(welded) => own + welded,
            None => own,
        }
    }

    /// Whether the node in slot `r` of `rotating` carries a child body.
    #[inline]
    pub fn carries(&self, r: usize) -> bool {
        self.carries.get(r).copied().unwrap_or(false)
    }

    /// Its number of modes m.
    pub fn mode_count(&self) -> usize {
        self.modal.modes.len()
    }

    /// Its modal coordinates η: their entries of `theta` (nq long).
    #[inline]
    pub fn eta<'a, T>(&self, theta: &'a [T]) -> &'a [T] {
        &theta[self.qpos_adr..self.qpos_adr + self.mode_count()]
    }

    /// Mode `k`'s stiffness ω² (unit modal mass).
    pub fn stiffness(&self, k: usize) -> f64 {
        self.modal.modes[k].angular_frequency.powi(2)
    }

    /// Mode `k`'s viscous damping 2ζω (unit modal mass).
    pub fn damping(&self, k: usize) -> f64 {
        let mode = &self.modal.modes[k];
        2.0 * mode.damping_ratio * mode.angular_frequency
    }

    /// ½ Σ ω_k² η_k² for the modal coordinates `eta`.
    pub fn strain_energy(&self, eta: &[f64]) -> f64 {
        eta.iter().enumerate().map(|(k, e)| 0.5 * self.stiffness(k) * e * e).sum()
    }
}

/// `body` in the frame of the link that carries it, its body frame being
/// `offset` (ᵇX_ₗ) on that link: positions, rotary inertias and mode
/// shapes turned into link axes and moved to the link origin.
pub(crate) fn on_link(body: &ModalBody, offset: &Transform) -> ModalBody {
    let to_link = offset.rot.transpose();
    let nodes = body
        .nodes
        .iter()
        .map(|node| Node {
            name: node.name.clone(),
            position: offset.trans + to_link * node.position,
            mass: node.mass,
            rotary_inertia: to_link * node.rotary_inertia * offset.rot,
        })
        .collect();
    let modes = body
        .modes
        .iter()
        .map(|mode| Mode {
            angular_frequency: mode.angular_frequency,
            damping_ratio: mode.damping_ratio,
            translation: mode.translation.iter().map(|t| to_link * t).collect(),
            rotation: mode.rotation.iter().map(|r| to_link * r).collect(),
        })
        .collect();
    ModalBody { body: body.body.clone(), nodes, modes }
}

impl super::Model {
    /// The flexible bodies' strain energy ½ Σ ω² η² at the configuration `theta` (nq).
    pub fn strain_energy(&self, theta: &[f64]) -> f64 {
        self.flexible.iter().map(|flexible| flexible.strain_energy(flexible.eta(theta))).sum()
    }

    /// The strain energy's derivative at `theta` along `direction` (both nq,
    /// θ's coordinates): Σ ω² η δη.
    pub fn strain_energy_derivative(&self, theta: &[f64], direction: &[f64]) -> f64 {
        self.flexible
            .iter()
            .flat_map(|flexible| {
                (0..flexible.mode_count()).map(|k| {
                    let at = flexible.qpos_adr + k;
                    flexible.stiffness(k) * theta[at] * direction[at]
                })
            })
            .sum()
    }
}
