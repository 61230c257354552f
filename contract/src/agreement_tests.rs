//! A property test over random layouts and option sets: every plant
//! variable's FMI 2.0 value reference, name and FMI 3.0 variable (arrays
//! or `--fmi3-scalars`) agree, both ways.

use proptest::prelude::*;

use crate::fmi3::{Fmi3Variables, TIME_VR};
use crate::plant::{ENERGY_PROJECTION_NAME, ENERGY_PROJECTION_VR, Layout, METHOD_NAME, METHOD_VR, RealVariable};
use crate::plant::{OptionalOutputs, SensorDependence};

fn outputs() -> impl Strategy<Value = OptionalOutputs> {
    proptest::collection::vec(any::<bool>(), OptionalOutputs::NAMES.len()).prop_map(|chosen| {
        let names: Vec<&str> =
            OptionalOutputs::NAMES.iter().zip(chosen).filter(|(_, chosen)| *chosen).map(|(name, _)| *name).collect();
        names.join(",").parse().expect("known names")
    })
}

fn layouts() -> impl Strategy<Value = Layout> {
    // A vehicle of up to 12 joints, each hinge/slide (1, 1), ball (4, 3) or free (7, 6).
    let joints = proptest::collection::vec(prop_oneof![Just((1, 1)), Just((4, 3)), Just((7, 6))], 1..12);
    let sizes = (0..6usize, 0..3usize, 0..10usize, 0..12usize, 0..3usize);
    (joints, sizes, outputs()).prop_map(|(joints, (nu, wrench_bodies, sensors, switches, na), outputs)| Layout {
        nq: joints.iter().map(|j| j.0).sum(),
        nv: joints.iter().map(|j| j.1).sum(),
        nu,
        wrench_inputs: 6 * wrench_bodies,
        na,
        sensordata: vec![SensorDependence::Motion; sensors],
        switches,
        eps_coupled: switches > 0,
        outputs,
        tree: None,
    })
}

fn table(layout: &Layout, scalars: bool) -> Fmi3Variables {
    Fmi3Variables::new(
        [(METHOD_VR, METHOD_NAME.to_string())],
        [(ENERGY_PROJECTION_VR, ENERGY_PROJECTION_NAME.to_string())],
        layout.real_blocks(),
        scalars,
    )
}

proptest! {
    #[test]
    fn fmi2_and_fmi3_value_references_and_names_agree(layout in layouts(), scalars in any::<bool>()) {
        let fmi3 = table(&layout, scalars);
        let reals: Vec<(u32, RealVariable)> = layout.real_variables().collect();
        let names: Vec<(u32, String)> = layout.real_blocks().iter().flat_map(|b| b.elements().collect::<Vec<_>>()).collect();
        prop_assert_eq!(reals.len(), names.len());
        for ((vr, variable), (named_vr, name)) in reals.iter().zip(&names) {
            // FMI 2.0: consecutive from 1, decoded both ways, named by the block as by the variable.
            prop_assert_eq!(vr, named_vr);
            prop_assert_eq!(layout.real_variable(*vr), Some(*variable));
            prop_assert_eq!(layout.value_reference(*variable), Some(*vr));
            prop_assert_eq!(layout.name(*variable), Some(name.clone()));
            // FMI 3.0: the variable holding it, at the element its name says.
            let (holder, k) = fmi3.real_element(*vr).expect("every Real has an FMI 3.0 variable");
            prop_assert!(holder.value_reference > TIME_VR);
            prop_assert_eq!(fmi3.get(holder.value_reference), Some(holder));
            let element_name = if holder.array {
                match holder.name.strip_prefix("der(") {
                    Some(state) => format!("der({}[{}])", state.trim_end_matches(')'), k + 1),
                    None => format!("{}[{}]", holder.name, k + 1),
                }
            } else {
                prop_assert_eq!(k, 0);
                holder.name.clone()
            };
            prop_assert_eq!(&element_name, name);
            prop_assert_eq!(holder.array, !scalars && name.contains('['));
            // A derivative's state is the element it differentiates, at the same index.
            if let RealVariable::DerTheta(j) | RealVariable::DerNu(j) | RealVariable::DerAct(j) = variable {
                let state = match variable {
                    RealVariable::DerTheta(_) => RealVariable::Theta(*j),
                    RealVariable::DerNu(_) => RealVariable::Nu(*j),
                    _ => RealVariable::Act(*j),
                };
                let state_vr = layout.value_reference(state).expect("the state exists");
                let (state_holder, state_k) = fmi3.real_element(state_vr).expect("held");
                prop_assert_eq!(holder.derivative_of, Some(state_holder.value_reference));
                prop_assert_eq!(state_k, k);
            } else {
                prop_assert_eq!(holder.derivative_of, None);
            }
        }
        // Nothing past the last Real; every FMI 3.0 Float64 covers Reals only.
        prop_assert_eq!(layout.real_variable(reals.len() as u32 + 1), None);
        let covered: usize = fmi3.iter().filter(|v| v.value_type == crate::fmi3::ValueType::Float64).map(|v| v.len).sum();
        prop_assert_eq!(covered, reals.len());
    }
}
