//! Once the whole document is read and compiled: the warnings on the
//! world body's geoms, the flexible bodies, and the [`Vehicle`] with its
//! flags applied.

use super::Reader;
use crate::math::Vec3;
use crate::mjcf::error::MjcfError;
use crate::mjcf::{Imported, MjcfWarning};
use crate::vehicle::Vehicle;

impl Reader {
    pub(super) fn finish(mut self, name: String) -> Result<Imported, MjcfError> {
        // MuJoCo's passive stage, which computes the gravity compensation,
        // stops before it when springs and dampers are both disabled (the
        // compensation still decided what fusestatic fused).
        if self.physics.spring_disabled && self.physics.damper_disabled {
            self.bodies.iter_mut().for_each(|body| body.gravcomp = 0.0);
        }
        self.warn_of_world_geoms();
        self.warnings.sort_by_key(|w| w.line);
        let gravity = if self.physics.gravity_disabled { Vec3::zeros() } else { self.physics.gravity };
        let flexible = self.modal_bodies()?;
        let vehicle = Vehicle {
            name,
            gravity,
            magnetic: self.physics.magnetic,
            bodies: self.bodies,
            sites: self.sites,
            actuators: self.actuators,
            sensors: self.sensors,
            actuation: self.physics.actuation,
            constraint_options: self.physics.constraint_options,
            equalities: std::mem::take(&mut self.equalities),
            sensors_disabled: self.physics.sensor_disabled,
            tendons: std::mem::take(&mut self.tendons),
            flexible,
        };
        Ok(Imported { vehicle, warnings: self.warnings, keyframes: self.keyframes })
    }

    /// The world body's geoms: one a tendon wraps around is used, and only
    /// its contacts are left out; any other is ignored. Their warnings come
    /// first, as when they were read.
    fn warn_of_world_geoms(&mut self) {
        let mut warnings = Vec::new();
        for geom in std::mem::take(&mut self.world_geoms) {
            let tendon = geom.name.as_ref().and_then(|name| self.wrap_obstacles.get(name));
            match tendon {
                None => warnings.push(geom.warning),
                Some(tendon) if geom.collides => warnings.push(MjcfWarning {
                    message: format!(
                        "used as the wrap obstacle of <{tendon}>; fixed to the world, it moves no mass, and its \
                         contacts are left out: nudyn models no contacts (MuJoCo would make contacts with it)"
                    ),
                    ..geom.warning
                }),
                Some(_) => {}
            }
        }
        self.warnings.splice(0..0, warnings);
    }
}
