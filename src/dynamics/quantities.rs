//! Kinetic energy, power and the vehicle's spatial momentum.

use super::{DynamicsError, require};
use crate::math::{Real, SpatialVec};
use crate::model::Model;
use crate::workspace::{Stage, Workspace};

/// K = ½|ν|² (paper (1.2), corrected: docs/DYNAMICS.md §1).
pub fn kinetic_energy(nu: &[f64]) -> f64 {
    0.5 * nu.iter().map(|x| x * x).sum::<f64>()
}

impl Workspace {
    /// K = ½|ν|² of the workspace's ν.
    pub fn kinetic_energy(&self) -> f64 {
        kinetic_energy(self.nu.as_slice())
    }

    /// Power of the applied ε: ν·ε (Lemma 3).
    pub fn power(&self, eps: &[f64]) -> f64 {
        self.nu.iter().zip(eps).map(|(n, e)| n * e).sum()
    }
}

impl<S: Real> Workspace<S> {
    /// Spatial momentum of all bodies and flexible bodies' nodes (angular
    /// about the world origin, then linear), in world coordinates. Armature is rotor inertia, not body
    /// momentum, so it is not included (as in MuJoCo).
    pub fn momentum(&mut self, model: &Model) -> Result<SpatialVec<S>, DynamicsError> {
        require(self, Stage::Velocity, "momentum")?;
        self.world_transforms(model);
        let mut total = SpatialVec::zeros();
        for (i, link) in model.links.iter().enumerate() {
            let h = link.inertia_times(&self.v_body[i]);
            // ⁱX₀ᵀ h: the link's momentum in world coordinates about the world origin.
            total += self.x_world[i].apply_transpose_force(&h);
        }
        for (flexible, state) in model.flexible.iter().zip(&self.flex) {
            // The nodes' momentum about R: 𝓘_RR V_R + U η̇.
            let (adr, m) = (flexible.dof_adr, flexible.mode_count());
            let rate = self.qvel.rows(adr, m);
            let mut h = state.rigid * self.v_body[flexible.link]
                + SpatialVec::from_iterator(
                    (0..6).map(|row| (0..m).map(|k| state.coupling[(row, k)] * rate[k]).fold(S::zero(), |a, b| a + b)),
                );
            // 𝓘 holds the articulated inertias of the children at nodes, whose links count above.
            h -= state.carried_momentum(flexible);
            total += self.x_world[flexible.link].apply_transpose_force(&h);
        }
        Ok(total)
    }
}
