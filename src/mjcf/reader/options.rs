//! `<compiler>` and `<option>`: the settings the rest of the reader follows,
//! each read from its attribute table.

use super::{ACTUATOR_GROUPS, Compiler, InertiaFromGeom, Physics, Reader};
use crate::math::Vec3;
use crate::mjcf::attributes::{Attribute, names, read_into, set};
use crate::mjcf::element::Element;
use crate::mjcf::error::MjcfError;

/// `<compiler>` (MuJoCo 4.0 schema): its attributes and how each is read.
/// `assetdir` comes before `meshdir`, as MuJoCo reads them, so that
/// `meshdir` wins.
pub(crate) const COMPILER_ATTRIBUTES: &[Attribute<Compiler>] = &[
    Attribute::into("alignfree", |c, e, a| set(&mut c.align_free, e.boolean(a)?)),
    Attribute::into("angle", |c, e, a| {
        set(&mut c.angles.degrees, e.keyword(a, &[("degree", true), ("radian", false)])?)
    }),
    Attribute::into("assetdir", |c, e, a| set(&mut c.mesh_dir, e.text(a).map(str::to_string))),
    Attribute::into("autolimits", |c, e, a| set(&mut c.autolimits, e.boolean(a)?)),
    Attribute::into("balanceinertia", |c, e, a| set(&mut c.balance_inertia, e.boolean(a)?)),
    Attribute::into("boundinertia", |c, e, a| set(&mut c.bound_inertia, e.non_negative(a)?)),
    Attribute::into("boundmass", |c, e, a| set(&mut c.bound_mass, e.non_negative(a)?)),
    Attribute::no_effect("conflict"),
    Attribute::checked("coordinate", |e, a| match e.text(a) {
        None | Some("local") => Ok(()),
        Some("global") => Err(e.unsupported("coordinate=\"global\" (removed from MuJoCo in version 2.3.3)")),
        Some(_) => Err(e.bad_value(a, "\"local\"")),
    }),
    Attribute::no_effect("discardvisual"),
    Attribute::into("eulerseq", |c, e, a| {
        let sequence = e.text(a).map(|sequence| {
            sequence
                .as_bytes()
                .try_into()
                .ok()
                .filter(|s: &[u8; 3]| s.iter().all(|c| b"xyzXYZ".contains(c)))
                .ok_or_else(|| e.bad_value(a, "3 letters from x, y, z, X, Y, Z"))
        });
        set(&mut c.angles.euler_seq, sequence.transpose()?)
    }),
    Attribute::into("fitaabb", |c, e, a| set(&mut c.fit_aabb, e.boolean(a)?)),
    Attribute::into("fusestatic", |c, e, a| set(&mut c.fuse_static, e.boolean(a)?)),
    Attribute::into("inertiafromgeom", |c, e, a| {
        let sources =
            [("false", InertiaFromGeom::Never), ("true", InertiaFromGeom::Always), ("auto", InertiaFromGeom::Auto)];
        set(&mut c.inertia_from_geom, e.keyword(a, &sources)?)
    }),
    Attribute::into("inertiagrouprange", |c, e, a| set(&mut c.inertia_groups, e.integers(a)?)),
    Attribute::into("meshdir", |c, e, a| set(&mut c.mesh_dir, e.text(a).map(str::to_string))),
    Attribute::no_effect("passthrough"),
    Attribute::no_effect("savecanonical"),
    Attribute::no_effect("savecompiled"),
    Attribute::no_effect("saveinertial"),
    Attribute::into("settotalmass", |c, e, a| {
        let total_mass = e.number(a)?.map(|total| {
            let warning = e.warning(format!(
                "settotalmass is deprecated in MuJoCo; all masses and inertias are scaled so the total mass is {total}"
            ));
            (total > 0.0).then_some((total, warning))
        });
        set(&mut c.total_mass, total_mass)
    }),
    Attribute::into("strippath", |c, e, a| set(&mut c.strip_path, e.boolean(a)?)),
    Attribute::no_effect("texturedir"),
    Attribute::no_effect("usethread"),
];

/// `<option>` (MuJoCo 4.0 schema): its attributes and how each is read.
/// Those for contacts and MuJoCo's iterative solver, which nudyn does not
/// use, are read for their syntax only (MuJoCo refuses more numbers than
/// each holds); `iterations` and `tolerance` by the reader, which warns
/// where they let MuJoCo stop short of the forces nudyn computes, and the
/// fluid settings, which it refuses when they would act.
pub(crate) const OPTION_ATTRIBUTES: &[Attribute<Physics>] = &[
    Attribute::into("actuatorgroupdisable", |p, e, a| {
        let groups = e.integer_list(a)?;
        if groups.as_ref().is_some_and(|groups| groups.iter().any(|g| !ACTUATOR_GROUPS.contains(g))) {
            return Err(e.bad_value(a, "actuator groups from 0 to 30"));
        }
        set(&mut p.disabled_actuator_groups, groups)
    }),
    Attribute::checked("ccd_iterations", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::checked("ccd_tolerance", |e, a| e.number(a).map(drop)),
    Attribute::no_effect("cone"),
    Attribute::by_reader("density"),
    Attribute::into("gravity", |p, e, a| set(&mut p.gravity, e.numbers::<3>(a)?.map(Vec3::from))),
    Attribute::checked("impratio", |e, a| e.number(a).map(drop)),
    Attribute::no_effect("integrator"),
    Attribute::by_reader("iterations"),
    Attribute::no_effect("jacobian"),
    Attribute::checked("ls_iterations", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::checked("ls_tolerance", |e, a| e.number(a).map(drop)),
    Attribute::into("magnetic", |p, e, a| set(&mut p.magnetic, e.numbers::<3>(a)?.map(Vec3::from))),
    Attribute::into("noslip_iterations", |p, e, a| {
        let iterations = e
            .integers::<1>(a)?
            .map(|[n]| u32::try_from(n).map_err(|_| e.bad_value(a, "a non-negative number of iterations")));
        set(&mut p.constraint_options.noslip_iterations, iterations.transpose()?)
    }),
    Attribute::into("noslip_tolerance", |p, e, a| set(&mut p.constraint_options.noslip_tolerance, e.number(a)?)),
    Attribute::checked("o_friction", |e, a| e.overwrite_numbers(a, &mut [0.0; 5])),
    Attribute::checked("o_margin", |e, a| e.number(a).map(drop)),
    Attribute::checked("o_solimp", |e, a| e.overwrite_numbers(a, &mut [0.0; 5])),
    Attribute::checked("o_solref", |e, a| e.overwrite_numbers(a, &mut [0.0; 2])),
    Attribute::checked("sdf_initpoints", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::checked("sdf_iterations", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::checked("sleep_tolerance", |e, a| e.number(a).map(drop)),
    Attribute::no_effect("solver"),
    Attribute::into("timestep", |p, e, a| {
        let timestep = e.number(a)?;
        if timestep.is_some_and(|timestep| timestep <= 0.0) {
            return Err(e.bad_value(a, "a positive time step"));
        }
        set(&mut p.constraint_options.timestep, timestep)
    }),
    Attribute::by_reader("tolerance"),
    Attribute::by_reader("viscosity"),
    Attribute::by_reader("wind"),
];

/// Refuses what would add fluid forces, which nudyn does not model: wind
/// first (it is what a file that sets it means), then a nonzero medium.
fn refuse_fluid_forces(element: &Element) -> Result<(), MjcfError> {
    if element.numbers::<3>("wind")?.is_some_and(|w| w != [0.0; 3]) {
        return Err(element.unsupported("wind acts through fluid forces, which nudyn does not model"));
    }
    for medium in ["density", "viscosity"] {
        if element.number(medium)?.is_some_and(|x| x != 0.0) {
            return Err(
                element.unsupported(format!("a nonzero medium {medium} adds fluid forces, which nudyn does not model"))
            );
        }
    }
    Ok(())
}

/// `<flag>` (MuJoCo 4.0 schema): every attribute takes "enable" or
/// "disable"; those of the iterative solver and the discrete integrators
/// are read for their syntax only, those of contacts only for the contact
/// warnings.
pub(crate) const FLAG_ATTRIBUTES: &[Attribute<Physics>] = &[
    Attribute::into("actuation", |p, e, a| set(&mut p.actuation.enabled, enabled(e, a)?)),
    Attribute::checked("autoreset", |e, a| enabled(e, a).map(drop)),
    Attribute::into("clampctrl", |p, e, a| set(&mut p.actuation.clamp_ctrl, enabled(e, a)?)),
    Attribute::into("constraint", |p, e, a| set(&mut p.constraint_disabled, disabled(e, a)?)),
    Attribute::into("contact", |p, e, a| set(&mut p.contact_disabled, disabled(e, a)?)),
    Attribute::into("damper", |p, e, a| set(&mut p.damper_disabled, disabled(e, a)?)),
    Attribute::checked("diagexact", |e, a| enabled(e, a).map(drop)),
    Attribute::checked("energy", |e, a| enabled(e, a).map(drop)),
    Attribute::into("equality", |p, e, a| set(&mut p.equality_disabled, disabled(e, a)?)),
    Attribute::checked("eulerdamp", |e, a| enabled(e, a).map(drop)),
    Attribute::into("filterparent", |p, e, a| set(&mut p.filterparent_disabled, disabled(e, a)?)),
    Attribute::into("frictionloss", |p, e, a| set(&mut p.frictionloss_disabled, disabled(e, a)?)),
    Attribute::checked("fwdinv", |e, a| enabled(e, a).map(drop)),
    Attribute::into("gravity", |p, e, a| set(&mut p.gravity_disabled, disabled(e, a)?)),
    Attribute::checked("invdiscrete", |e, a| enabled(e, a).map(drop)),
    Attribute::checked("ipc", |e, a| enabled(e, a).map(drop)),
    Attribute::into("island", |p, e, a| set(&mut p.constraint_options.islands, enabled(e, a)?)),
    Attribute::into("limit", |p, e, a| set(&mut p.limit_disabled, disabled(e, a)?)),
    Attribute::checked("midphase", |e, a| enabled(e, a).map(drop)),
    Attribute::checked("multiccd", |e, a| enabled(e, a).map(drop)),
    Attribute::checked("nativeccd", |e, a| enabled(e, a).map(drop)),
    Attribute::checked("override", |e, a| enabled(e, a).map(drop)),
    Attribute::into("refsafe", |p, e, a| set(&mut p.constraint_options.refsafe, enabled(e, a)?)),
    Attribute::into("sensor", |p, e, a| set(&mut p.sensor_disabled, disabled(e, a)?)),
    Attribute::checked("sleep", |e, a| match enabled(e, a)? {
        Some(true) => Err(e.unsupported("sleeping bodies (flag sleep=\"enable\") freeze the dynamics")),
        _ => Ok(()),
    }),
    Attribute::checked("speculative", |e, a| enabled(e, a).map(drop)),
    Attribute::into("spring", |p, e, a| set(&mut p.spring_disabled, disabled(e, a)?)),
    Attribute::checked("warmstart", |e, a| enabled(e, a).map(drop)),
];

/// A flag's "enable" (true) or "disable" (false).
fn enabled(element: &Element, attribute: &'static str) -> Result<Option<bool>, MjcfError> {
    element.keyword(attribute, &[("enable", true), ("disable", false)])
}

/// A flag's "disable" (true) or "enable" (false).
fn disabled(element: &Element, attribute: &'static str) -> Result<Option<bool>, MjcfError> {
    Ok(enabled(element, attribute)?.map(|on| !on))
}

impl Reader {
    pub(super) fn read_compiler(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(&names(COMPILER_ATTRIBUTES))?;
        read_into(COMPILER_ATTRIBUTES, &mut self.compiler, element)?;
        for child in element.children() {
            match child.tag() {
                "lengthrange" => self.warnings.push(child.ignored()),
                _ => return Err(child.unknown()),
            }
        }
        Ok(())
    }

    pub(super) fn read_option(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(&names(OPTION_ATTRIBUTES))?;
        read_into(OPTION_ATTRIBUTES, &mut self.physics, element)?;
        refuse_fluid_forces(element)?;
        // Fewer iterations or a looser tolerance than MuJoCo's defaults (100,
        // 1e-8) let MuJoCo stop short of the constraint forces nudyn computes.
        let iterations = element.integers::<1>("iterations")?.map(|[n]| n);
        let tolerance = element.number("tolerance")?;
        let loose = [
            iterations.filter(|&n| n < 100).map(|n| format!("iterations={n}")),
            tolerance.filter(|&t| t > 1e-8).map(|t| format!("tolerance={t}")),
        ];
        let loose: Vec<String> = loose.into_iter().flatten().collect();
        if !loose.is_empty() {
            self.warnings.push(element.warning(format!(
                "nudyn solves the constraint problem exactly; MuJoCo with {} will differ",
                loose.join(" and ")
            )));
        }
        let mut flag_seen: Option<Element> = None;
        for child in element.children() {
            if child.tag() != "flag" {
                return Err(child.unknown());
            }
            if let Some(first) = &flag_seen {
                return Err(child.repeated(first));
            }
            child.check_attributes(&names(FLAG_ATTRIBUTES))?;
            read_into(FLAG_ATTRIBUTES, &mut self.physics, &child)?;
            flag_seen = Some(child);
        }
        Ok(())
    }
}
