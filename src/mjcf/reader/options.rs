//! `<compiler>` and `<option>`: the settings the rest of the reader follows.

use super::{ACTUATOR_GROUPS, COMPILER_ATTRIBUTES, FLAG_ATTRIBUTES, InertiaFromGeom, OPTION_ATTRIBUTES, Reader};
use crate::math::Vec3;
use crate::mjcf::element::Element;
use crate::mjcf::error::MjcfError;
use std::collections::HashMap;

impl Reader {
    pub(super) fn read_compiler(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(COMPILER_ATTRIBUTES)?;
        let compiler = &mut self.compiler;
        match element.text("coordinate") {
            None | Some("local") => {}
            Some("global") => {
                return Err(element.unsupported("coordinate=\"global\" (removed from MuJoCo in version 2.3.3)"));
            }
            Some(_) => return Err(element.bad_value("coordinate", "\"local\"")),
        }
        if let Some(degrees) = element.keyword("angle", &[("degree", true), ("radian", false)])? {
            compiler.angles.degrees = degrees;
        }
        if let Some(sequence) = element.text("eulerseq") {
            compiler.angles.euler_seq = sequence
                .as_bytes()
                .try_into()
                .ok()
                .filter(|s: &[u8; 3]| s.iter().all(|c| b"xyzXYZ".contains(c)))
                .ok_or_else(|| element.bad_value("eulerseq", "3 letters from x, y, z, X, Y, Z"))?;
        }
        let sources =
            [("false", InertiaFromGeom::Never), ("true", InertiaFromGeom::Always), ("auto", InertiaFromGeom::Auto)];
        if let Some(source) = element.keyword("inertiafromgeom", &sources)? {
            compiler.inertia_from_geom = source;
        }
        if let Some(groups) = element.integers("inertiagrouprange")? {
            compiler.inertia_groups = groups;
        }
        if let Some(bound) = element.non_negative("boundmass")? {
            compiler.bound_mass = bound;
        }
        if let Some(bound) = element.non_negative("boundinertia")? {
            compiler.bound_inertia = bound;
        }
        if let Some(balance) = element.boolean("balanceinertia")? {
            compiler.balance_inertia = balance;
        }
        if let Some(fit_aabb) = element.boolean("fitaabb")? {
            compiler.fit_aabb = fit_aabb;
        }
        if let Some(autolimits) = element.boolean("autolimits")? {
            compiler.autolimits = autolimits;
        }
        if let Some(align) = element.boolean("alignfree")? {
            compiler.align_free = align;
        }
        if let Some(total) = element.number("settotalmass")? {
            let warning = element.warning(format!(
                "settotalmass is deprecated in MuJoCo; all masses and inertias are scaled so the total mass is {total}"
            ));
            compiler.total_mass = (total > 0.0).then_some((total, warning));
        }
        // MuJoCo reads assetdir first, so that meshdir wins.
        for attribute in ["assetdir", "meshdir"] {
            if let Some(dir) = element.text(attribute) {
                compiler.mesh_dir = dir.to_string();
            }
        }
        if let Some(strip) = element.boolean("strippath")? {
            compiler.strip_path = strip;
        }
        if let Some(fuse) = element.boolean("fusestatic")? {
            compiler.fuse_static = fuse;
        }
        for child in element.children() {
            match child.tag() {
                "lengthrange" => self.warnings.push(child.ignored()),
                _ => return Err(child.unknown()),
            }
        }
        Ok(())
    }

    pub(super) fn read_option(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(OPTION_ATTRIBUTES)?;
        if let Some(gravity) = element.numbers::<3>("gravity")? {
            self.physics.gravity = Vec3::from(gravity);
        }
        if let Some(magnetic) = element.numbers::<3>("magnetic")? {
            self.physics.magnetic = Vec3::from(magnetic);
        }
        if let Some(timestep) = element.number("timestep")? {
            if timestep <= 0.0 {
                return Err(element.bad_value("timestep", "a positive time step"));
            }
            self.physics.constraint_options.timestep = timestep;
        }
        if let Some([iterations]) = element.integers::<1>("noslip_iterations")? {
            self.physics.constraint_options.noslip_iterations = u32::try_from(iterations)
                .map_err(|_| element.bad_value("noslip_iterations", "a non-negative number of iterations"))?;
        }
        if let Some(tolerance) = element.number("noslip_tolerance")? {
            self.physics.constraint_options.noslip_tolerance = tolerance;
        }
        if let Some(groups) = element.integer_list("actuatorgroupdisable")? {
            if groups.iter().any(|g| !ACTUATOR_GROUPS.contains(g)) {
                return Err(element.bad_value("actuatorgroupdisable", "actuator groups from 0 to 30"));
            }
            self.physics.disabled_actuator_groups = groups;
        }
        // Read for their syntax only: they set contacts, which nudyn does not
        // model, and MuJoCo's iterative solver, which nudyn does not use.
        // MuJoCo refuses more numbers than each holds.
        element.overwrite_numbers("o_solref", &mut [0.0; 2])?;
        element.overwrite_numbers("o_solimp", &mut [0.0; 5])?;
        element.overwrite_numbers("o_friction", &mut [0.0; 5])?;
        for attribute in ["o_margin", "impratio", "ls_tolerance", "ccd_tolerance", "sleep_tolerance"] {
            element.number(attribute)?;
        }
        for attribute in ["ls_iterations", "ccd_iterations", "sdf_iterations", "sdf_initpoints"] {
            element.integers::<1>(attribute)?;
        }
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
        if element.numbers::<3>("wind")?.is_some_and(|w| w != [0.0; 3]) {
            return Err(element.unsupported("wind acts through fluid forces, which nudyn does not model"));
        }
        for medium in ["density", "viscosity"] {
            if element.number(medium)?.is_some_and(|x| x != 0.0) {
                return Err(element
                    .unsupported(format!("a nonzero medium {medium} adds fluid forces, which nudyn does not model")));
            }
        }
        let mut flag_seen: Option<Element> = None;
        for child in element.children() {
            if child.tag() != "flag" {
                return Err(child.unknown());
            }
            if let Some(first) = &flag_seen {
                return Err(child.repeated(first));
            }
            flag_seen = Some(child);
            child.check_attributes(FLAG_ATTRIBUTES)?;
            let mut disabled = HashMap::new();
            for &flag in FLAG_ATTRIBUTES {
                if let Some(off) = child.keyword(flag, &[("enable", false), ("disable", true)])? {
                    disabled.insert(flag, off);
                }
            }
            if disabled.get("sleep") == Some(&false) {
                return Err(child.unsupported("sleeping bodies (flag sleep=\"enable\") freeze the dynamics"));
            }
            let physics = &mut self.physics;
            if let Some(&off) = disabled.get("island") {
                physics.constraint_options.islands = !off;
            }
            if let Some(&off) = disabled.get("refsafe") {
                physics.constraint_options.refsafe = !off;
            }
            for (flag, target) in [
                ("gravity", &mut physics.gravity_disabled),
                ("spring", &mut physics.spring_disabled),
                ("damper", &mut physics.damper_disabled),
                ("constraint", &mut physics.constraint_disabled),
                ("frictionloss", &mut physics.frictionloss_disabled),
                ("limit", &mut physics.limit_disabled),
                ("equality", &mut physics.equality_disabled),
                ("sensor", &mut physics.sensor_disabled),
            ] {
                if let Some(&off) = disabled.get(flag) {
                    *target = off;
                }
            }
            for (flag, target) in
                [("actuation", &mut physics.actuation.enabled), ("clampctrl", &mut physics.actuation.clamp_ctrl)]
            {
                if let Some(&off) = disabled.get(flag) {
                    *target = !off;
                }
            }
        }
        Ok(())
    }
}
