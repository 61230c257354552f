//! MuJoCo's gravity compensation (body `gravcomp`, joint
//! `actuatorgravcomp`) compiled onto the links: each compensated body
//! pushes with −gravcomp · m · g at its centre of mass, so a link takes
//! the sum over its bodies of gravcomp · m and gravcomp · m · c, as it
//! takes their masses and mass moments for gravity (docs/DYNAMICS.md §5).

use serde::{Deserialize, Serialize};

use crate::math::Vec3;
use crate::vehicle::Vehicle;

/// The compensated weight on one link.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompensatedLink {
    /// The link.
    pub link: usize,
    /// Σ gravcomp · m over the link's bodies (kg).
    pub mass: f64,
    /// Σ gravcomp · m · c (c: a body's centre of mass in link coordinates).
    pub mass_moment: Vec3,
}

/// MuJoCo's `qfrc_gravcomp` and where it goes: into the passive forces,
/// or for the joints with `actuatorgravcomp` into `qfrc_actuator`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GravityCompensation {
    /// The links carrying compensated bodies, ascending, each once; empty
    /// when MuJoCo applies no compensation (zero gravity, or no body with
    /// gravcomp > 0).
    pub links: Vec<CompensatedLink>,
    /// The dofs of the joints with `actuatorgravcomp`, ascending: their
    /// share is an actuator force, clamped with the joint's
    /// `actuatorfrcrange`, and nothing when the vehicle has no actuators
    /// or `<flag actuation="disable"/>` (MuJoCo's rule).
    pub actuator_dofs: Vec<usize>,
}

impl GravityCompensation {
    /// Whether there is nothing to compensate: the passes skip it.
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// Adds a body of mass `mass`, centre of mass `com` (link coordinates)
    /// and `gravcomp` on `link`.
    pub(super) fn add_body(&mut self, link: usize, gravcomp: f64, mass: f64, com: &Vec3) {
        if gravcomp == 0.0 || mass == 0.0 {
            return;
        }
        let compensated = gravcomp * mass;
        // A welded body can come after its link's descendants in document order.
        match self.links.iter_mut().find(|c| c.link == link) {
            Some(known) => {
                known.mass += compensated;
                known.mass_moment += compensated * com;
            }
            None => self.links.push(CompensatedLink { link, mass: compensated, mass_moment: compensated * com }),
        }
    }

    /// What MuJoCo applies of the compensation collected for `vehicle`:
    /// nothing without gravity, and nothing unless some body has
    /// gravcomp > 0 (its `flg_gravcomp`; bodies with negative gravcomp
    /// then count too). `actuator_dofs` gives the dofs of every joint with
    /// `actuatorgravcomp`, in dof order.
    pub(super) fn applied(self, vehicle: &Vehicle, actuator_dofs: Vec<usize>) -> GravityCompensation {
        let any_positive = vehicle.bodies.iter().any(|b| b.gravcomp > 0.0);
        if vehicle.gravity == Vec3::zeros() || !any_positive || self.links.is_empty() {
            return GravityCompensation::default();
        }
        let mut links = self.links;
        links.sort_by_key(|c| c.link);
        GravityCompensation { links, actuator_dofs }
    }
}
