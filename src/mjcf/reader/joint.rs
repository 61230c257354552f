//! Joints: their settings resolved into the vehicle's joints, limits and
//! constraint parameters.

use super::replicate::Named;
use super::{JointSpec, JointTarget, Reader, claim_name};
use crate::math::Vec3;
use crate::mjcf::defaults::{JointSettings, Limited};
use crate::mjcf::element::{Element, Origin};
use crate::mjcf::error::MjcfError;
use crate::mjcf::orientation::normalized;
use crate::vehicle::{Joint, JointConstraints, JointKind, JointLimit, SpringDamper};

impl Reader {
    /// Checks a body's joints and turns them into [`Joint`]s.
    pub(super) fn build_joints(
        &mut self,
        body_name: &str,
        parent: Option<usize>,
        specs: Vec<JointSpec>,
    ) -> Result<Vec<Joint>, MjcfError> {
        let count = specs.len();
        let mut joints = Vec::with_capacity(count);
        let mut after_ball = false;
        let mut dofs = 0;
        for (k, joint) in specs.into_iter().enumerate() {
            let JointSpec { at, name: named, settings: s, suffix, .. } = joint;

            let rotational = matches!(s.kind, JointKind::Hinge | JointKind::Ball);
            if rotational && after_ball {
                return Err(at.unsupported(
                    "a hinge or ball joint after a ball joint in the same body (MuJoCo allows no rotation after a ball joint)",
                ));
            }
            after_ball |= s.kind == JointKind::Ball;

            if s.kind == JointKind::Free {
                if count > 1 {
                    return Err(at.invalid("a free joint must be the only joint of its body"));
                }
                if parent.is_some() {
                    return Err(at.invalid("a free joint must belong to a body directly inside <worldbody>"));
                }
            } else {
                self.check_limits(&at, &s)?;
            }
            dofs += s.kind.nv();
            if dofs > 6 {
                return Err(at.invalid("more than 6 degrees of freedom in one body"));
            }

            let axis = match s.kind {
                // Not zero (checked when read), but a <frame> may turn a tiny one into zero.
                JointKind::Hinge | JointKind::Slide => normalized(Vec3::from(s.axis))
                    .ok_or_else(|| at.invalid("the axis, turned by the <frame>s around it, is zero"))?,
                JointKind::Ball | JointKind::Free => Vec3::z(),
            };
            let (reference, springref) = match s.kind {
                JointKind::Hinge => {
                    let angles = &self.compiler.angles;
                    (angles.radians(s.reference), angles.radians(s.springref))
                }
                JointKind::Slide => (s.reference, s.springref),
                JointKind::Ball | JointKind::Free => (0.0, 0.0),
            };
            let actuator_force_range = self.actuator_force_range(&at, &s)?;
            let name = named.as_deref().map_or_else(
                || format!("{body_name}_joint{k}"),
                |name| self.replicated_name(Named::Joint, name, &suffix),
            );
            if named.is_some() {
                claim_name(&mut self.joint_names, "joint", &name, &at)?;
            }
            let range = match s.kind {
                JointKind::Hinge | JointKind::Ball if self.joint_limited(&s) => {
                    s.range.map(|x| self.compiler.angles.radians(x))
                }
                _ => s.range,
            };
            let limited = s.kind != JointKind::Free && self.joint_limited(&s);
            if named.is_some() {
                self.joint_targets.insert(name.clone(), JointTarget { kind: s.kind, range, limited });
            }
            joints.push(Joint {
                name,
                kind: s.kind,
                pos: if s.kind == JointKind::Free { Vec3::zeros() } else { Vec3::from(s.pos) },
                axis,
                reference,
                springref,
                stiffness: if self.physics.spring_disabled { 0.0 } else { s.stiffness[0] },
                damping: if self.physics.damper_disabled { 0.0 } else { s.damping[0] },
                armature: s.armature,
                actuator_force_range,
                actuator_gravcomp: s.actuator_gravcomp,
                springdamper: (s.springdamper != [0.0; 2]).then_some(SpringDamper {
                    time_constant: s.springdamper[0],
                    damping_ratio: s.springdamper[1],
                    spring: !self.physics.spring_disabled,
                    damper: !self.physics.damper_disabled,
                }),
                constraints: self.joint_constraints(&s, range),
                line: at.line,
            });
        }
        Ok(joints)
    }

    /// The joint's friction loss and limits as constraints, less what the
    /// `<flag>`s turn off (`range` in radians for hinges).
    pub(super) fn joint_constraints(&self, settings: &JointSettings, range: [f64; 2]) -> JointConstraints {
        let physics = &self.physics;
        let on = |disabled: bool| !physics.constraint_disabled && !disabled;
        let limited = settings.kind != JointKind::Free && self.joint_limited(settings);
        JointConstraints {
            frictionloss: if on(physics.frictionloss_disabled) { settings.frictionloss } else { 0.0 },
            friction: settings.friction_soft,
            limit: (limited && on(physics.limit_disabled)).then_some(JointLimit {
                range,
                margin: settings.margin,
                soft: settings.limit_soft,
            }),
        }
    }

    /// Whether a joint other than a free one has limits (MuJoCo's rule).
    pub(super) fn joint_limited(&self, settings: &JointSettings) -> bool {
        let [low, high] = settings.range;
        settings.limited == Limited::Yes || (settings.limited == Limited::Auto && low < high)
    }

    /// MuJoCo's checks of joint limits.
    pub(super) fn check_limits(&mut self, at: &Origin, settings: &JointSettings) -> Result<(), MjcfError> {
        let [low, high] = settings.range;
        if settings.limited == Limited::Auto && settings.range != [0.0; 2] && !self.compiler.autolimits {
            return Err(at.invalid(
                "'range' without 'limited' while <compiler autolimits=\"false\">; give 'limited' or remove 'range'",
            ));
        }
        if !self.joint_limited(settings) {
            return Ok(());
        }
        if settings.kind == JointKind::Ball {
            if low != 0.0 {
                return Err(at.invalid("the first 'range' value of a ball joint must be 0"));
            }
        } else if low >= high {
            return Err(at.invalid("the first 'range' value must be smaller than the second"));
        }
        Ok(())
    }

    /// A hinge or slide joint's limits on the total actuator force
    /// (`actuatorfrclimited`, `actuatorfrcrange`); ball and free joints have none.
    pub(super) fn actuator_force_range(
        &self,
        at: &Origin,
        settings: &JointSettings,
    ) -> Result<Option<[f64; 2]>, MjcfError> {
        if matches!(settings.kind, JointKind::Ball | JointKind::Free) {
            return Ok(None);
        }
        self.limits(at, "actuatorfrc", settings.actuator_force_limited, settings.actuator_force_range)
    }

    /// MuJoCo's rule for an `<prefix>limited` and `<prefix>range` pair: with
    /// "auto", limited when the range is not empty (a range given without the
    /// flag is an error under `autolimits="false"`); a limited range must be
    /// increasing.
    pub(super) fn limits(
        &self,
        at: &Origin,
        prefix: &str,
        limited: Limited,
        range: [f64; 2],
    ) -> Result<Option<[f64; 2]>, MjcfError> {
        if limited == Limited::Auto && range != [0.0; 2] && !self.compiler.autolimits {
            return Err(at.invalid(format!(
                "'{prefix}range' without '{prefix}limited' while <compiler autolimits=\"false\">; \
                 give '{prefix}limited' or remove '{prefix}range'"
            )));
        }
        let on = limited == Limited::Yes || (limited == Limited::Auto && range[0] < range[1]);
        if on && range[0] >= range[1] {
            return Err(at.invalid(format!(
                "invalid '{prefix}range' {} {}: the first value must be smaller than the second",
                range[0], range[1]
            )));
        }
        Ok(on.then_some(range))
    }
}

/// MuJoCo's checks of a `<joint>`'s values, made as it is read (`settings`:
/// its class's with its own applied).
pub(super) fn check_joint_values(element: &Element, s: &JointSettings) -> Result<(), MjcfError> {
    let origin = |attribute: &str| if element.has(attribute) { "" } else { " (from its default class)" };
    if s.springdamper != [0.0; 2] && !(s.springdamper[0] > 0.0 && s.springdamper[1] > 0.0) {
        return Err(element.bad_value("springdamper", "two positive values (time constant, damping ratio)"));
    }
    if s.springyield != 0.0 {
        return Err(element.unsupported(format!("springyield{}: yielding springs", origin("springyield"))));
    }
    for (attribute, coefficients) in [("stiffness", &s.stiffness), ("damping", &s.damping)] {
        if coefficients[1..] != [0.0; 2] {
            return Err(
                element.unsupported(format!("nonlinear {attribute}{} (more than one coefficient)", origin(attribute)))
            );
        }
    }
    if matches!(s.kind, JointKind::Hinge | JointKind::Slide) && normalized(Vec3::from(s.axis)).is_none() {
        return Err(element.bad_value("axis", "a vector that is not zero"));
    }
    Ok(())
}
