//! What the force and torque sensors need beyond the bodies' masses: on
//! which MuJoCo body each external force acts. MuJoCo's interaction force
//! of a body with its parent (`cfrc_int`) is its subtree's inertial force
//! less the external forces on the subtree (`cfrc_ext`: the wrench inputs,
//! MuJoCo's `xfrc_applied`, and the forces of connect and weld
//! constraints), so each must be put on its own body, not merely on the
//! link carrying it.

use serde::{Deserialize, Serialize};

use crate::vehicle::{EqualityObjects, Vehicle};

/// The bodies the external forces act on, when a force or torque sensor
/// needs them (else empty).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct InteractionBodies {
    /// The body of each wrench input, in the order of
    /// [`Model::wrench_bodies`](super::Model::wrench_bodies).
    pub wrench_inputs: Vec<usize>,
    /// The two bodies of each compiled equality constraint (`None`: the
    /// world, or a joint coupling, which acts on no body).
    pub equalities: Vec<[Option<usize>; 2]>,
}

impl InteractionBodies {
    /// The bodies of `vehicle`'s wrench inputs on `wrench_bodies` (names
    /// checked by their compilation) and of its active equalities, in the
    /// order the compiled constraints keep them.
    pub(super) fn of(vehicle: &Vehicle, wrench_bodies: &[String]) -> InteractionBodies {
        let body = |name: &String| vehicle.bodies.iter().position(|b| &b.name == name);
        let wrench_inputs = wrench_bodies.iter().filter_map(body).collect();
        let equalities = vehicle
            .equalities
            .iter()
            .filter(|e| e.active)
            .map(|e| match e.kind.objects() {
                Some(EqualityObjects::Bodies(first, second)) => [first, second],
                Some(EqualityObjects::Sites(first, second)) => [vehicle.sites[first].body, vehicle.sites[second].body],
                None => [None, None],
            })
            .collect();
        InteractionBodies { wrench_inputs, equalities }
    }
}
